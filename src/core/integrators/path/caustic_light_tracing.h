#pragma once
/// \file Light tracing for the caustics a path tracer cannot find: BDPT's t = 1
/// strategy, restricted to the paths whose light reaches a rough surface only through a
/// Dirac (mirror or glass) bounce, MIS-weighted against the camera paths that hit the
/// light through the same chain (the pt integrator; path_integrator.cpp).
///
/// The class of paths. A path z0 (lens) z1 … z_{n−1} z_n (a point y on a light) belongs
/// to it when (a) the vertex next to the light, z_{n−1}, scattered by a Dirac lobe, and
/// (b) z1, the first surface the camera sees, scattered by a non-Dirac lobe (the lens
/// connection needs a BSDF value there), with n − 1 ≤ max_depth scattering vertices.
/// Next-event estimation cannot make such a path (its light edge leaves a Dirac
/// vertex), so the path tracer finds it only when a BSDF-sampled ray happens to hit the
/// light through the chain: a 2 cm light seen through a glass ball is a firefly in a
/// few pixels (sequences/hard/caustic_lsdse), a 0.4 mm bulb in a mirror never
/// (bulb_room). The light tracer makes the same path from the other end: a light path
/// y → z_{n−1} → … → z1, connected to the lens at z1. Both strategies sample every path
/// of the class (where the other's density is 0 the first gets weight 1), so the sum
/// is the path tracer's estimator with less variance; paths outside the class keep the
/// path tracer's own weights.
///
/// MIS weights (power heuristic): r = p_LT / p_PT, the ratio of the two strategies'
/// densities of the path in area measure. The geometry terms of the shared edges
/// cancel, as do the Dirac coefficients (taken as 1 at both ends), leaving
///
///     r = p_light(y) · p⊥_emit(y → z_{n−1}) · Π_{i=2..n−1} p⊥(z_i → z_{i−1})
///         / ( p_cam(z1) · Π_{i=1..n−1} p⊥(z_i → z_{i+1}) )
///
/// with p_light = the light's pmf here × its area density at y, p⊥ a solid-angle density
/// over |cos| at the vertex (shading normal), p_cam the camera's area density of z1 (the
/// window's, as in lens_light_tracing.h), Dirac vertices contributing 1. The camera path
/// gets 1 / (1 + r²), the light path r² / (1 + r²). Russian roulette and pass-through
/// crossings are left out of r: the weights are the same function of the path on both
/// sides, so they sum to one and the estimate is unbiased whatever they leave out.
///
/// Emission is guided to the casters (lights/emission_guide.h, shared with BDPT): a light
/// path that does not hit a Dirac surface first is wasted, so the direction is drawn
/// uniformly in the cone of one of the casters' bounding spheres, density
/// p_emit(ω) = (1/K) Σ_k [ω ∈ cone_k] / Ω_k; where it is 0 the light tracer cannot make
/// the path and the camera path keeps weight 1. Light chosen by power
/// among the finite, non-Dirac lights (area, sphere, disk, cylinder, emissive
/// triangles); the rest (dome, distant, point lights) are not traced and their paths
/// stay the path tracer's.
///
/// One light path per image pixel and pass, keyed (seed, pixel, sample) in its own
/// stream (RngStream::caustic_light), splatted with LensPass's splats.
#include "integrators/bdpt/camera_importance.h"
#include "lights/emission_guide.h"
#include "math/vec.h"
#include "sampling/discrete_distribution.h"

#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

namespace cmlt {

class Camera;
class Scene;

class CausticLightTracing {
public:
    /// `margin`: the film window's (PixelFilter::margin); `max_depth`: the path tracer's.
    CausticLightTracing(const Scene& scene, const Camera& camera, int width, int height, float margin,
                        int max_depth);

    /// Something to trace: a caster, a traced light, a camera that can be connected to.
    bool active() const { return m_active; }
    /// Lights traced (stats).
    size_t light_count() const { return m_lights.size(); }
    size_t caster_count() const { return m_guide.caster_count(); }

    /// Per Scene light index, 1 for a light this tracer traces (all 0 when inactive):
    /// the light-traced caustics of the path partition (PathPartition::set_traced).
    std::vector<uint8_t> traced_lights() const {
        std::vector<uint8_t> t(m_slot.size(), 0);
        if (m_active)
            for (uint32_t i : m_lights) t[i] = 1;
        return t;
    }
    /// Camera side. The area density with which the camera samples z1 (point `p`,
    /// geometric normal `ng`) from lens point `p_lens`: the denominator's first factor.
    float camera_density(const Vec3& p_lens, const Vec3& p, const Vec3& ng) const;
    /// Camera side. p_light(y) · p⊥_emit(y → toward) for light `light_index` (0 if the
    /// light is not traced or the direction cannot be drawn).
    float light_density(uint32_t light_index, const Vec3& y, const Vec3& toward) const;
    /// The camera path's weight given r (1 / (1 + r²)).
    static float camera_weight(double r) {
        const double w = 1.0 / (1.0 + r * r);
        return std::isfinite(w) ? float(w) : 0.f;
    }

    /// One light path keyed (seed, pixel, sample): appends its lens connections
    /// (raster position, weighted value) to `out`; counts rays and shadow rays.
    void trace(uint64_t seed, uint32_t pixel, uint32_t sample, bool motion_blur,
               std::vector<std::pair<Vec2, Spectrum>>& out, uint64_t* rays, uint64_t* shadow_rays) const;

private:
    const Scene& m_scene;
    CameraImportance m_importance;
    int m_max_depth;
    bool m_active = false;
    EmissionGuide m_guide;  ///< every light path's direction (lights/emission_guide.h)
    std::vector<uint32_t> m_lights;  ///< traced lights (indices into Scene::light)
    std::vector<int32_t> m_slot;     ///< Scene light index -> index into m_lights, or -1
    DiscreteDistribution m_dist;     ///< over m_lights, by power
};

}  // namespace cmlt
