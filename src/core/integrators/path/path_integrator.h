#pragma once
/// \file The path-tracing frame loop (integrator "pt"): passes of one sample per pixel
/// over image tiles (oneTBB), each sample keyed by (seed, pixel, sample index) through
/// PixelSampler and estimated by PathTracer::pixel_sample (path_tracer.h), accumulated by
/// the Film in sample order per pixel — bit-identical images at any thread count.
#include "integrators/common/render_settings.h"

namespace cmlt {

class Scene;

/// Render a committed scene with the path tracer (called by render(); settings validated).
RenderResult render_pt(const Scene& scene, const RenderSettings& settings, const ProgressCallback& progress);

}  // namespace cmlt
