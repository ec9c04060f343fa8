#pragma once
/// \file The definition of PathTracer::li, generic over the random source (see
/// path_tracer.h). Included by path_tracer.cpp (instantiated for PixelSampler) and by
/// integrators that drive the same sampling routine with their own sampler (mlt/).
#include "integrators/path/caustic_light_tracing.h"
#include "integrators/path/lens_light_tracing.h"
#include "integrators/path/path_tracer.h"

#include "materials/bsdf.h"
#include "materials/material_eval.h"
#include "sampling/mis.h"
#include "scene/scene.h"

#include <algorithm>
#include <cmath>
#include <new>

namespace cmlt {

template <class Sampler>
Spectrum PathTracer::li(const Ray& camera_ray, Sampler& sampler, PathCounters& c,
                        const SceneHit* first_hit) const {
    static_assert(is_path_sampler_v<Sampler>, "PathTracer::li reads a PathSampler (base/sampler.h)");
    PathState st;
    begin(st, camera_ray, c);
    for (;;) {
        if (st.bounce == 0 && first_hit) {
            step(st, *first_hit, sampler, c);
        } else {
            step(st, m_scene.intersect(st.ray), sampler, c);
        }
        if (st.has_shadow) {
            float pass_pdf = 1.f;
            const float tr = m_scene.transmittance(st.shadow, st.shadow_light, &pass_pdf);
            finish_shadow(st, tr, pass_pdf);
        }
        if (st.done) break;
    }
    return st.L;
}

inline void PathTracer::begin(PathState& st, const Ray& camera_ray, PathCounters& c) const {
    // Built in place from the members' initialisers (every member has one): assigning a
    // temporary copied it through the stack, whose 16-byte reloads of 8-byte stores
    // stalled store forwarding, and value-initialisation (PathState()) zero-fills the
    // whole state with a rep stos first.
    st.~PathState();
    new (&st) PathState;
    st.ray = camera_ray;
    st.prev_p = camera_ray.o;  // the lens point until the first scattering
    c.samples += 1;
    c.camera_rays += 1;
}

template <class Sampler>
void PathTracer::step(PathState& st, const SceneHit& hit, Sampler& sampler, PathCounters& c) const {
    static_assert(is_path_sampler_v<Sampler>, "PathTracer::step reads a PathSampler (base/sampler.h)");
    const Scene& scene = m_scene;
    // `depth` counts scattering events; `bounce` counts hits, pass-through crossings
    // included, and keys the random dimensions (the two are equal in a scene without
    // pass-through surfaces). A crossing (a cut-out, an ior-1 interface) is no
    // scattering event: the path goes on in the same direction from the same previous
    // vertex, so next-event estimation through it (Scene::transmittance) and BSDF
    // sampling through it are two strategies for the same path, weighted by MIS.
    const uint32_t bounce = st.bounce++;
    const Ray& ray = st.ray;
    c.rays += 1;

    // Emission of light `light` (a Scene light index, -1: none) seen by this ray,
    // MIS-weighted against light sampling.
    auto add_emitted = [&](const Spectrum& le, float light_pdf_sa, int32_t light) {
        if (is_black(le) || st.depth < m_min_depth) return;
        if (m_partition &&
            !m_partition->wants(m_partition->caustic(st.last_specular, st.diffuse_before_last, st.first_specular,
                                                     st.n_diffuse,
                                                     m_partition->traced(st.first_dirac, st.specular_bounce, light))))
            return;
        if (st.depth == 0 || st.specular_bounce) {
            st.L += st.beta * le;
        } else {
            st.L += st.beta * le * power_heuristic(st.prev_bsdf_pdf, light_pdf_sa);
        }
    };
    const bool direct = st.depth == 0 || st.specular_bounce;  // emission not MIS-weighted
    if (hit.kind == SceneHit::Kind::miss) {
        for (uint32_t li : scene.infinite_lights()) {
            const Light& light = scene.light(li);
            float pdf = 0.f;  // pdf_li, for the MIS weight of emission not seen directly
            Spectrum le = light.le_escape_pdf(ray.d, st.prev_p, direct ? nullptr : &pdf);
            if (is_black(le)) continue;
            float pl = direct ? 0.f : scene.light_pmf(li) * pdf;
            add_emitted(le, pl, int32_t(li));
        }
        st.done = true;
        return;
    }
    if (hit.kind == SceneHit::Kind::light) {
        float pl = direct ? 0.f
                          : scene.light_pmf(hit.light_index) * scene.light(hit.light_index).pdf_li(st.prev_p, ray.d);
        const int32_t light = int32_t(hit.light_index);
        if (m_lens_light && st.depth == 0) {
            // shared with the (1, 1) light samples (prev_p: the lens point)
            add_emitted(hit.le * m_lens_light->camera_hit_weight(st.prev_p, ray.o + ray.d * hit.t, hit.light_index), pl,
                        light);
        } else if (st.lt > 0.0 && st.specular_bounce) {
            // a caustic path, shared with the light paths (prev_p: the Dirac vertex)
            const float a = m_caustic->light_density(hit.light_index, ray.o + ray.d * hit.t, st.prev_p);
            add_emitted(hit.le * CausticLightTracing::camera_weight(st.lt * double(a)), pl, light);
        } else {
            add_emitted(hit.le, pl, light);
        }
        st.done = true;  // analytic lights do not reflect
        return;
    }
    const SurfaceInteraction& si = hit.si;
    const Material& mat = scene.material(si.material_id);
    if (mat.is_emissive()) {
        const int32_t li = scene.triangle_light_index(si.instance_id, si.prim_id);
        float pl = 0.f;
        if (!direct && li >= 0)
            pl = scene.light_pmf(size_t(li)) * scene.triangle_light(size_t(li)).pdf_li_point(st.prev_p, si.p);
        Spectrum le = emitted_radiance(mat, si.uv, scene.textures());
        if (st.lt > 0.0 && st.specular_bounce && !is_black(le)) {
            // a caustic path, shared with the light paths
            const float a = li >= 0 ? m_caustic->light_density(uint32_t(li), si.p, st.prev_p) : 0.f;
            le *= CausticLightTracing::camera_weight(st.lt * double(a));
        }
        add_emitted(le, pl, li);
    }

    // Stop after max_depth scattering events (a pass-through surface may still be
    // crossed: that adds none).
    const bool last = st.depth == m_max_depth;
    const bool passes = scene.material_passes(si.material_id);
    if (last && !passes) {
        st.done = true;
        return;
    }
    const bool specular = m_partition && m_partition->specular(si.material_id);
    scatter(st, bounce, si, si.wo, make_bsdf(mat, si, scene.textures()), passes, last, specular, sampler, c);
}

inline bool PathTracer::enter_opaque_hit(PathState& st, PathCounters& c, uint32_t* bounce) const {
    *bounce = st.bounce++;
    c.rays += 1;
    if (st.depth == m_max_depth) {  // max_depth scattering events: an opaque hit ends it
        st.done = true;
        return false;
    }
    return true;
}

template <class Sampler>
void PathTracer::step(PathState& st, const LambertHit& hit, Sampler& sampler, PathCounters& c) const {
    // What step(SceneHit) does for a surface hit whose material constant_lambert accepts:
    // no emission, opaque, the Lambertian make_bsdf builds.
    uint32_t bounce;
    if (!enter_opaque_hit(st, c, &bounce)) return;
    const HitGeometry& g = *hit.geometry;
    scatter(st, bounce, g.sp, g.wo, Bsdf(LambertianBsdf(*hit.reflectance), g.ns, g.sp.ng), false, false, false, sampler,
            c);
}

template <class Sampler>
void PathTracer::step(PathState& st, const BsdfHit& hit, Sampler& sampler, PathCounters& c) const {
    // What step(SceneHit) does for a surface hit on a material that emits nothing and lets
    // no ray through, with the BSDF make_bsdf returns there.
    uint32_t bounce;
    if (!enter_opaque_hit(st, c, &bounce)) return;
    const HitGeometry& g = *hit.geometry;
    const bool specular = m_partition && m_partition->specular(g.material_id);
    scatter(st, bounce, g.sp, g.wo, *hit.bsdf, false, false, specular, sampler, c);
}

template <class Sampler>
void PathTracer::scatter(PathState& st, uint32_t bounce, const SurfacePoint& sp, const Vec3& wo, const Bsdf& bsdf,
                         bool passes, bool last, bool specular, Sampler& sampler, PathCounters& c) const {
    const Scene& scene = m_scene;
    const Vec3& ns = bsdf.shading_normal();
    sampler.set_dimension(1 + bounce * k_dims_per_bounce);
    float u_light = sampler.get1d();
    Vec2 u_light_pos = sampler.get2d();
    Vec2 u_bsdf = sampler.get2d();
    float u_lobe = sampler.get1d();
    float u_rr = sampler.get1d();

    // Next-event estimation: one light chosen by power; its shadow ray is left pending.
    if (!last && bsdf.has_non_delta() && scene.light_count() > 0 && st.depth + 1 >= m_min_depth &&
        (!m_partition || st.wants_next_event(*m_partition, specular))) {
        float pmf = 0.f;
        size_t li = scene.sample_light(u_light, &pmf);
        const Light& light = scene.light(li);
        LightSample ls = light.sample_li(sp.p, u_light_pos);
        if (ls.valid() && pmf > 0.f) {
            float bsdf_pdf = 0.f;
            Spectrum f = bsdf.eval_pdf(wo, ls.wi, TransportMode::Radiance, &bsdf_pdf) * std::fabs(dot(ls.wi, ns));
            if (!is_black(f)) {
                if (std::isinf(ls.dist)) {
                    st.shadow = sp.spawn_ray(ls.wi);
                } else {
                    st.shadow = sp.spawn_ray_to(shadow_target(ls.p_light, ls.n_light, ls.error_scale, ls.wi));
                }
                c.shadow_rays += 1;
                c.rays += 1;
                // Through pass-through surfaces: attenuated by tr; BSDF sampling
                // would make this path with density bsdf.pdf * pass_pdf.
                st.has_shadow = true;
                st.shadow_light = uint32_t(li);
                st.shadow_delta = ls.is_delta;
                st.shadow_light_pdf = pmf * ls.pdf;
                st.shadow_bsdf_pdf = ls.is_delta ? 0.f : bsdf_pdf;
                st.shadow_f = st.beta * f * ls.li;
            }
        }
    }

    // Continue the path by sampling the BSDF.
    BsdfSample bs = bsdf.sample(wo, u_bsdf, u_lobe);
    if (!bs.valid()) {
        st.done = true;
        return;
    }
    if (bs.pass_through && passes) {
        // Cross: throughput T / p, and the density with which BSDF sampling reaches
        // the next vertex gains the factor p (MIS against NEE's pass_pdf);
        // specular_bounce, prev_p and depth stay as they are.
        st.beta *= bs.f * (std::fabs(dot(bs.wi, ns)) / bs.pdf);
        if (is_black(st.beta) || !is_finite(st.beta)) {
            st.done = true;
            return;
        }
        st.prev_bsdf_pdf *= bs.pdf;
        st.ray = sp.spawn_ray(bs.wi);
        return;
    }
    if (last) {
        st.done = true;
        return;
    }
    st.beta *= bs.f * (std::fabs(dot(bs.wi, ns)) / bs.pdf);
    if (is_black(st.beta) || !is_finite(st.beta)) {
        st.done = true;
        return;
    }
    if (m_caustic) {
        // The camera side of r (caustic_light_tracing.h): 1 / (p_cam(z1) p⊥(z1 → z2))
        // at the first vertex (0 if it scattered by a Dirac lobe: no path of the class),
        // then each rough vertex's reverse over forward density; Dirac vertices give 1.
        const float cos_i = std::fabs(dot(bs.wi, ns));
        const float fwd = cos_i > 0.f ? bs.pdf / cos_i : 0.f;
        if (st.depth == 0) {
            const double den = bs.is_delta ? 0.0 : double(m_caustic->camera_density(st.prev_p, sp.p, sp.ng)) * fwd;
            st.lt = den > 0.0 ? 1.0 / den : 0.0;
        } else if (st.lt > 0.0 && !bs.is_delta) {
            const float cos_o = std::fabs(dot(wo, ns));
            const float rev = cos_o > 0.f ? bsdf.pdf(bs.wi, wo) / cos_o : 0.f;
            st.lt = fwd > 0.f ? st.lt * double(rev) / double(fwd) : 0.0;
        }
    }
    st.specular_bounce = bs.is_delta;
    if (st.depth == 0) st.first_dirac = bs.is_delta;
    if (bs.is_transmission) st.eta_scale *= bs.eta * bs.eta;
    st.prev_bsdf_pdf = bs.pdf;
    st.prev_p = sp.p;
    st.ray = sp.spawn_ray(bs.wi);
    st.diffuse_before_last = st.diffuse_seen;
    st.diffuse_seen = st.diffuse_seen || !specular;
    st.last_specular = specular;
    if (st.depth == 0) st.first_specular = specular;
    if (!specular && st.n_diffuse < 2) ++st.n_diffuse;

    // Russian roulette.
    if (st.depth + 1 >= k_rr_start_depth) {
        float q = std::min(0.95f, max_component(st.beta) * st.eta_scale);
        if (!(u_rr < q)) {
            st.done = true;
            return;
        }
        st.beta /= q;
    }
    ++st.depth;
}

}  // namespace cmlt
