#pragma once
/// \file Emission aimed at the casters: directions drawn toward the objects that can
/// bend light into caustics.
///
/// A light path that does not reach a mirror or glass surface first cannot become a
/// caustic path (L S+ D … E), and a small glass object far from the light is hit by a
/// tiny fraction of the directions a light emits into (a 30 cm ball 1.5 m away: about
/// 1 %). The guide keeps the bounding spheres of the *casters* — the instances with a
/// material that may be specular (analysis/scene_probes.h) — and draws a direction
/// uniformly in the cone one of them subtends from the emitting point, the caster chosen
/// uniformly. Its solid-angle density is
///
///     p_guide(ω | y) = (1/K) Σ_k [ω ∈ cone_k(y)] / Ω_k(y),   Ω_k = 2π (1 − cos θ_k)
///
/// (4π's density for a point inside a sphere), a deterministic function of (y, ω), so a
/// strategy that sampled a direction some other way can ask for it in its MIS weights.
/// More than 64 casters are guided to as one sphere around them all (the density loops
/// over the casters). Spheres are the instances' world bounding boxes at time 0: a
/// moving caster is aimed at less well, never wrongly (the density is the one used).
///
/// Users: the path tracer's caustic light tracing (every light path guided) and BDPT's
/// light subpaths, which mix the guide with the light's own emission (bdpt_tracer.h).
#include "lights/light.h"
#include "math/vec.h"

#include <vector>

namespace cmlt {

class Scene;

/// Can `light`'s emission be guided (and traced from a point and direction of the
/// caller's choosing)? Finite, not Dirac, and giving its radiance toward a direction
/// (Light::le_toward: area, sphere, disk, cylinder and mesh lights).
bool emission_guidable(const Light& light);
/// A point on `light` from `u_pos` as Light::sample_le draws it (its area density in
/// pdf_pos), for a caller that chooses the direction itself: sample_le with a direction
/// sample every light accepts (the two-sided mesh light spends the direction's first
/// number on the side: 0.5 would be the rim of its hemisphere, pdf 0, no sample). The
/// returned d, le and pdf_dir are sample_le's and not meant to be used.
LightLeSample emission_point(const Light& light, const Vec2& u_pos);

class EmissionGuide {
public:
    EmissionGuide() = default;
    /// The casters of `scene` (none: inactive).
    explicit EmissionGuide(const Scene& scene);

    bool active() const { return !m_casters.empty(); }
    size_t caster_count() const { return m_casters.size(); }

    /// Solid-angle density of the guided direction `w` (unit) from `y`.
    float pdf(const Vec3& y, const Vec3& w) const;
    /// A guided direction from `y`: `u_caster` in [0, 1) picks the caster, `u` the
    /// direction in its cone. Needs active().
    Vec3 sample(const Vec3& y, float u_caster, const Vec2& u) const;
    /// The same from two numbers: `u.x` picks the caster and, rescaled to [0, 1) within
    /// the caster's share, is the cone's first number.
    Vec3 sample(const Vec3& y, const Vec2& u) const;

    /// The share of the sphere of directions from `y` that the casters' cones cover:
    /// Σ_k (1 − cos θ_k) / 2, at most 1 (1 inside a sphere; overlapping cones counted
    /// twice, so an upper bound). About how often emission that ignores the casters
    /// heads for one (caster_coverage).
    double coverage(const Vec3& y) const;

private:
    struct Caster {
        Vec3 center;
        float radius;
    };
    std::vector<Caster> m_casters;
};

/// EmissionGuide::coverage from a point of each light that can be guided (its
/// emission_point at the middle of its position sample), averaged over those lights
/// weighted by the probability the scene picks them (Scene::light_pmf): how often a
/// light subpath would head for a caster without the guide. 0 without casters or
/// guidable lights. The Metropolis integrators' auto guiding asks it (mlt_context.h).
double caster_coverage(const Scene& scene, const EmissionGuide& guide);

}  // namespace cmlt
