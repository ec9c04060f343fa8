#pragma once
/// \file The BDPT frame loop (settings.integrator == "bdpt").
///
/// Passes: pass k traces one BDPT sample in every pixel (tiles over oneTBB). The t >= 2
/// estimate of each pixel goes to a pass buffer; light-tracing splats (t = 1) land
/// anywhere, so each tile keeps its own splat list, and after the pass the lists are
/// added into a splat image in tile order -- the same order and so the same float sums
/// whatever the thread count (bit-identical images for a seed). Then every pixel gets
/// one film sample: its pass estimate plus its splat sum. The passes are independent
/// estimates of the image, so the film's per-pixel variance (over passes) includes the
/// light-tracing noise.
#include "integrators/common/render_settings.h"

namespace cmlt {

class Scene;

/// Render a committed scene with BDPT (called by render(); settings already validated).
RenderResult render_bdpt(const Scene& scene, const RenderSettings& settings,
                         const ProgressCallback& progress);

}  // namespace cmlt
