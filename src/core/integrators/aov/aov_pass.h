#pragma once
/// \file Integrator-independent AOV pass: albedo, shading normal, depth of the first hit.
///
/// For each pixel, `samples` camera rays are traced to their first hit only (no light
/// transport, so the pass is cheap and the same for every integrator). Sample s of pixel
/// p uses the film position of `PixelSampler(seed, key(p), s)` (key: the beauty's,
/// film/pass_splatter.h KeyShift) under the pixel filter
/// (PixelFilter::film_position: for the one-pixel box exactly the camera ray of pt's
/// sample s; for a wider filter drawn from the filter, filter importance sampling, where
/// the beauty splats uniform samples to its neighbours — film/pass_splatter.h — the same
/// filtered quantity): deterministic, independent of thread count. Albedo and normal are
/// filtered with the beauty image's filter (each sample weighted by its f/pdf); depth is
/// not (below).
///
/// Conventions (per pixel, over its samples):
///  * albedo: filter-weighted mean (as the film's) over all samples of the first hit's diffuse colour (rendering-space RGB,
///    ACEScg), its texture looked up at the hit's st (materials/material_eval.h). A ray that escapes contributes 0. A ray that hits an analytic light's
///    emitting side contributes the light's radiance clamped to [0, 1] (the denoiser
///    convention for emitters); an emissive mesh contributes its material's diffuse.
///  * normal: world-space unit shading normal (the normal map applied, as the integrators'
///    BSDF sees it), turned to face the camera (toward the ray
///    origin); the normalised filter-weighted mean of the hitting samples' normals. Analytic lights give
///    the direction back to the camera. No hit: (0, 0, 0).
///  * depth (Z): distance of the hit point along the camera's viewing axis (local -Z),
///    in world units; the *closest* hitting sample of the filter's footprint (nearest
///    sample, not filtered: an average of depths across an edge is a depth of nothing). No
///    hit: 0, which never occurs for a hit because near clipping is > 0 or the hit is in
///    front of the camera. Always finite.
#include "integrators/common/render_settings.h"
#include "scene/scene.h"

#include <vector>

namespace cmlt {

struct AovResult {
    int width = 0, height = 0;
    std::vector<float> albedo;  ///< (H, W, 3), row 0 at the top
    std::vector<float> normal;  ///< (H, W, 3)
    std::vector<float> depth;   ///< (H, W)
    uint64_t rays = 0;
    double time_s = 0;
};

/// Run the AOV pass with `settings.width/height/seed/threads` (other fields unused).
/// Commits the scene if it has uncommitted edits. Throws SettingsError / SceneError.
AovResult render_aovs(Scene& scene, const RenderSettings& settings, int samples = 4);

}  // namespace cmlt
