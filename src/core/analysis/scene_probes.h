#pragma once
/// \file Cheap probe paths that tell the frame's scene analysis (cmlt/analysis/effects.py)
/// what no static look at the arrays can: whether a caustic can form where the camera
/// sees it, and how hard it is for a camera path to find the light.
///
/// Nothing is rendered: a few thousand rays, single-threaded, a few milliseconds on the
/// sequences. Random numbers are keyed by (seed, probe index, dimension), so the answer
/// is the same on every machine and at any thread count.
///
/// **Near-specular vertex.** A hit whose UsdPreviewSurface parameters (textures and
/// primvars applied at the hit) have roughness < `specular_roughness` and whose
/// near-Dirac lobes carry at least half of the weight: metal (metallic >= 0.5, metallic
/// workflow), glass (1 - opacity >= 0.5 with |ior - 1| >= 1e-3, not a cut-out), or a
/// mirror (specular workflow, max(specularColor) >= 0.5). Clearcoat alone (4 %) and the
/// legacy Lambert material never are. Pass-through crossings (cut-outs, ior-1 surfaces)
/// are no vertices: the probes step through them as the integrators do.
///
/// **Caustic paths** are light paths L S+ D whose diffuse vertex D the camera sees:
/// directly (D inside the image, an unoccluded segment to the camera on the lit side of
/// D), or through a specular chain (D on the lit side of a triangle where a visibility
/// probe's camera path ended after a specular vertex: a caustic seen through glass or in
/// a mirror; triangle granularity, so a large triangle counts as a whole): the paths a path tracer can only find by hitting a light through the specular
/// chain, which the caustic perturbation of DESIGN.md §3 and BDPT's light tracing
/// handle. Two estimators of the flux they carry onto camera-visible diffuse surfaces:
///  * `light_paths` emitted light paths (light chosen by power, Light::sample_le; for
///    infinite lights a disk covering the scene, as BDPT does), followed through at most
///    `max_chain` specular vertices: they also give the flux that lands on
///    camera-visible diffuse surfaces straight from a light (`direct_flux`);
///  * `targeted_paths` paths aimed at points drawn uniformly (by area) on the triangles
///    whose material can be near-specular: a light sample toward the point, the segment
///    checked from the light side (the first hit must be that triangle), then the chain.
///    These find a small glass object that few emitted paths hit.
/// Both are unbiased estimates of the same flux (per second, rendering-space luminance);
/// `caustic_flux` is the targeted one when there are candidate triangles.
///
/// **Visibility probes.** `camera_paths` camera rays on a stratified grid over the image
/// find their first diffuse vertex x1 (through specular chains; they run first, and mark
/// the triangles seen through a chain); `light_samples` light
/// samples at x1 give `direct_visible` (the fraction that reach a light unoccluded, on
/// the lit side); one cosine-sampled bounce from x1 to x2 and the same light samples at
/// x2 give `bounce_visible`. A room lit through a narrow gap has both small.
#include "scene/scene.h"

#include <cstdint>

namespace cmlt {

/// Can any material of the scene be near-specular somewhere (the rule above with
/// roughness below `max_roughness`, constants or the deciding inputs textured / read
/// from primvars)? The Metropolis integrators' auto camera technique asks (mlt/technique.h).
bool scene_may_be_specular(const Scene& scene, float max_roughness = 0.2f);
/// The same rule for one material (the Metropolis integrators' path partition asks it
/// per material: integrators/common/path_partition.h).
bool material_may_be_specular(const Material& material, float max_roughness = 0.2f);

struct ProbeOptions {
    int width = 64, height = 64;     ///< image the camera covers (its aspect frames it)
    uint64_t seed = 0;
    uint32_t light_paths = 1024;     ///< emitted light paths
    uint32_t targeted_paths = 1024;  ///< light paths aimed at near-specular candidates
    uint32_t camera_paths = 256;     ///< camera rays of the visibility probes
    uint32_t light_samples = 4;      ///< light samples per probed vertex
    int max_chain = 8;               ///< specular vertices followed, at most
    float specular_roughness = 0.2f; ///< near-Dirac below this roughness (not alpha)
    void validate() const;           ///< throws SettingsError naming the field
};

struct ProbeResult {
    // light paths
    uint32_t light_paths = 0;          ///< started (a valid emitted ray)
    uint32_t light_hit_specular = 0;   ///< first vertex near-specular
    uint32_t light_caustics = 0;       ///< emitted paths that are caustic paths
    double direct_flux = 0.0;          ///< onto camera-visible diffuse points, straight from a light
    double caustic_flux_emitted = 0.0; ///< the emitted paths' caustic flux estimate
    // targeted paths
    double candidate_area = 0.0;       ///< m², triangles whose material can be near-specular
    uint32_t targeted_paths = 0;       ///< drawn (0 without candidates)
    uint32_t targeted_reached = 0;     ///< the light reaches the point, and it is near-specular
    uint32_t targeted_caustics = 0;    ///< ... and the chain ends on a camera-visible diffuse point
    double caustic_flux_targeted = 0.0;
    // visibility
    uint32_t camera_paths = 0;
    uint32_t camera_diffuse_hits = 0;  ///< camera rays that found a diffuse vertex x1
    uint32_t camera_specular_first = 0;///< ... through at least one specular vertex
    uint32_t camera_escaped = 0;       ///< camera rays that left the scene or hit a light
    float direct_visible = 0.f;        ///< light samples at x1 that reach a light
    float bounce_visible = 0.f;        ///< light samples at x2 that reach a light
    float lit_hits = 0.f;              ///< x1 with at least one of its light samples reaching
    /// Where the light the camera sees comes from, per camera diffuse hit x1 (luminance,
    /// from the same light samples): the direct irradiance at x1, and the one-bounce
    /// indirect irradiance through the cosine-sampled bounce to x2 (π times the radiance
    /// x2 sends back toward x1 from its own light samples; 0 where the bounce escapes;
    /// 8 bounces per hit, the first the one bounce_visible counts) — means over the hits, and the indirect estimator's relative variance per bounce,
    /// E[I²] / E[I]² − 1: large where indirect light comes from small hot spots (a
    /// ceiling half a metre above a small bright light) that few bounces find.
    double direct_irradiance = 0.0;
    double indirect_irradiance = 0.0;
    double indirect_rel_var = 0.0;
};

/// Runs the probes on a committed scene with a camera. Throws SceneError otherwise.
ProbeResult probe_scene(const Scene& scene, const ProbeOptions& options);

}  // namespace cmlt
