#pragma once
/// \file The definition of PathTracer::li, generic over the random source (see
/// path_tracer.h). Included by path_tracer.cpp (instantiated for PixelSampler) and by
/// integrators that drive the same sampling routine with their own sampler (mlt/).
#include "integrators/path/path_tracer.h"

#include "materials/bsdf.h"
#include "materials/material_eval.h"
#include "sampling/mis.h"
#include "scene/scene.h"

#include <algorithm>
#include <cmath>

namespace cmlt {

template <class Sampler>
Spectrum PathTracer::li(const Ray& camera_ray, Sampler& sampler, PathCounters& c,
                        const SceneHit* first_hit) const {
    static_assert(is_path_sampler_v<Sampler>, "PathTracer::li reads a PathSampler (base/sampler.h)");
    const Scene& scene = m_scene;
    Spectrum L(0.f), beta(1.f);
    Ray ray = camera_ray;
    bool specular_bounce = false;
    float eta_scale = 1.f;  // product of eta^2 over refractions: undoes radiance scaling for RR
    float prev_bsdf_pdf = 0.f;
    Vec3 prev_p;
    c.samples += 1;
    c.camera_rays += 1;

    // `depth` counts scattering events; `bounce` counts hits, pass-through crossings
    // included, and keys the random dimensions (the two are equal in a scene without
    // pass-through surfaces). A crossing (a cut-out, an ior-1 interface) is no
    // scattering event: the path goes on in the same direction from the same previous
    // vertex, so next-event estimation through it (Scene::transmittance) and BSDF
    // sampling through it are two strategies for the same path, weighted by MIS.
    int depth = 0;
    for (uint32_t bounce = 0;; ++bounce) {
        // Find the next vertex.
        SceneHit hit = (bounce == 0 && first_hit) ? *first_hit : scene.intersect(ray);
        c.rays += 1;

        // Emission seen by this ray, MIS-weighted against light sampling.
        auto add_emitted = [&](const Spectrum& le, float light_pdf_sa) {
            if (is_black(le) || depth < m_min_depth) return;
            if (depth == 0 || specular_bounce) {
                L += beta * le;
            } else {
                L += beta * le * power_heuristic(prev_bsdf_pdf, light_pdf_sa);
            }
        };
        if (hit.kind == SceneHit::Kind::miss) {
            for (uint32_t li : scene.infinite_lights()) {
                const Light& light = scene.light(li);
                Spectrum le = light.le_escape(ray.d);
                if (is_black(le)) continue;
                float pl = (depth == 0 || specular_bounce)
                               ? 0.f
                               : scene.light_pmf(li) * light.pdf_li(prev_p, ray.d);
                add_emitted(le, pl);
            }
            break;
        }
        if (hit.kind == SceneHit::Kind::light) {
            float pl = (depth == 0 || specular_bounce)
                           ? 0.f
                           : scene.light_pmf(hit.light_index) *
                                 scene.light(hit.light_index).pdf_li(prev_p, ray.d);
            add_emitted(hit.le, pl);
            break;  // analytic lights do not reflect
        }
        const SurfaceInteraction& si = hit.si;
        const Material& mat = scene.material(si.material_id);
        if (mat.is_emissive()) {
            float pl = 0.f;
            if (depth > 0 && !specular_bounce) {
                int32_t li = scene.triangle_light_index(si.instance_id, si.prim_id);
                if (li >= 0)
                    pl = scene.light_pmf(size_t(li)) *
                         scene.triangle_light(size_t(li)).pdf_li_point(prev_p, si.p);
            }
            add_emitted(emitted_radiance(mat, si.uv, scene.textures()), pl);
        }

        // Stop after max_depth scattering events (a pass-through surface may still be
        // crossed: that adds none).
        const bool last = depth == m_max_depth;
        if (last && !scene.material_passes(si.material_id)) break;

        Bsdf bsdf = make_bsdf(mat, si, scene.textures());
        const Vec3 wo = si.wo;
        const Vec3& ns = bsdf.shading_normal();
        sampler.set_dimension(1 + bounce * k_dims_per_bounce);
        float u_light = sampler.get1d();
        Vec2 u_light_pos = sampler.get2d();
        Vec2 u_bsdf = sampler.get2d();
        float u_lobe = sampler.get1d();
        float u_rr = sampler.get1d();

        // Next-event estimation: one light chosen by power.
        if (!last && bsdf.has_non_delta() && scene.light_count() > 0 && depth + 1 >= m_min_depth) {
            float pmf = 0.f;
            size_t li = scene.sample_light(u_light, &pmf);
            const Light& light = scene.light(li);
            LightSample ls = light.sample_li(si.p, u_light_pos);
            if (ls.valid() && pmf > 0.f) {
                Spectrum f = bsdf.eval(wo, ls.wi) * std::fabs(dot(ls.wi, ns));
                if (!is_black(f)) {
                    Ray shadow;
                    if (std::isinf(ls.dist)) {
                        shadow = si.spawn_ray(ls.wi);
                    } else {
                        shadow = si.spawn_ray_to(shadow_target(ls.p_light, ls.n_light, ls.error_scale, ls.wi));
                    }
                    c.shadow_rays += 1;
                    c.rays += 1;
                    // Through pass-through surfaces: attenuated by tr; BSDF sampling
                    // would make this path with density bsdf.pdf * pass_pdf.
                    float pass_pdf = 1.f;
                    const float tr = scene.transmittance(shadow, &pass_pdf);
                    if (tr > 0.f) {
                        float light_pdf = pmf * ls.pdf;
                        float w = ls.is_delta ? 1.f
                                              : power_heuristic(light_pdf,
                                                                bsdf.pdf(wo, ls.wi) * pass_pdf);
                        L += beta * f * ls.li * (tr * w / light_pdf);
                    }
                }
            }
        }

        // Continue the path by sampling the BSDF.
        BsdfSample bs = bsdf.sample(wo, u_bsdf, u_lobe);
        if (!bs.valid()) break;
        if (bs.pass_through && scene.material_passes(si.material_id)) {
            // Cross: throughput T / p, and the density with which BSDF sampling reaches
            // the next vertex gains the factor p (MIS against NEE's pass_pdf);
            // specular_bounce, prev_p and depth stay as they are.
            beta *= bs.f * (std::fabs(dot(bs.wi, ns)) / bs.pdf);
            if (is_black(beta) || !is_finite(beta)) break;
            prev_bsdf_pdf *= bs.pdf;
            ray = si.spawn_ray(bs.wi);
            continue;
        }
        if (last) break;
        beta *= bs.f * (std::fabs(dot(bs.wi, ns)) / bs.pdf);
        if (is_black(beta) || !is_finite(beta)) break;
        specular_bounce = bs.is_delta;
        if (bs.is_transmission) eta_scale *= bs.eta * bs.eta;
        prev_bsdf_pdf = bs.pdf;
        prev_p = si.p;
        ray = si.spawn_ray(bs.wi);

        // Russian roulette.
        if (depth + 1 >= k_rr_start_depth) {
            float q = std::min(0.95f, max_component(beta) * eta_scale);
            if (!(u_rr < q)) break;
            beta /= q;
        }
        ++depth;
    }
    return L;
}

}  // namespace cmlt
