#pragma once
/// \file The integrator interface: what render() calls for `RenderSettings::integrator`.
///
/// An integrator is one frame loop, a function from a committed scene and validated
/// settings to the frame's image and statistics (RenderResult). Each lives in its own
/// folder, integrators/<name>/, split as Tungsten splits its integrators: the frame loop
/// (<name>_integrator.{h,cpp}: threads, passes or chain rounds, budgets, the result) and
/// the per-thread path work (the tracer: path_tracer.h, bdpt_tracer.h, the chains of
/// pssmlt_chain.h and cmlt_chain.h). Integrators are called once per frame, so a plain
/// function table is all the dispatch they need (integrators/common/render.cpp); the
/// per-sample interfaces are static (base/sampler.h).
///
/// Contract of an IntegratorFn:
///  * the scene is committed and has a camera, the settings passed validate();
///  * `progress(done, total)`, if set, is called on the calling thread between chunks of
///    work; returning false stops the frame after the current chunk (RenderResult::
///    cancelled, the image normalised by the work done);
///  * the image is a pure function of (scene, settings) for a sample budget, whatever
///    `settings.threads` (a time budget makes the amount of work machine-dependent);
///  * bad input throws SettingsError / SceneError naming the field; a non-finite sample
///    never reaches the image (it is counted in RenderStats::nan_samples).
#include "integrators/common/render_settings.h"

namespace cmlt {

class Scene;

using IntegratorFn = RenderResult (*)(const Scene& scene, const RenderSettings& settings,
                                      const ProgressCallback& progress);

/// One row of the integrator table: the `RenderSettings::integrator` spelling and its
/// frame loop.
struct IntegratorEntry {
    const char* name;
    IntegratorFn render;
};

}  // namespace cmlt
