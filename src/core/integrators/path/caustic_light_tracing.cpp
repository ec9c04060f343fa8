// Light tracing for the path tracer's caustic paths; see caustic_light_tracing.h.
#include "integrators/path/caustic_light_tracing.h"

#include "analysis/scene_probes.h"
#include "cameras/camera.h"
#include "lights/light.h"
#include "materials/bsdf.h"
#include "materials/material_eval.h"
#include "math/frame.h"
#include "sampling/rng.h"
#include "sampling/rng_domains.h"
#include "sampling/warp.h"
#include "scene/interaction.h"
#include "scene/scene.h"

#include <algorithm>
#include <cmath>

namespace cmlt {

CausticLightTracing::CausticLightTracing(const Scene& scene, const Camera& camera, int width, int height,
                                         float margin, int max_depth)
    : m_scene(scene), m_importance(camera, width, height, margin), m_max_depth(max_depth),
      m_guide(scene), m_slot(scene.light_count(), -1) {
    // A light path needs at least a Dirac vertex and the rough vertex it connects from.
    if (!m_importance.connectable() || max_depth < 2 || !m_guide.active()) return;
    std::vector<double> power;
    for (size_t i = 0; i < scene.light_count(); ++i) {
        const Light& l = scene.light(i);
        if (!emission_guidable(l)) continue;
        m_slot[i] = int32_t(m_lights.size());
        m_lights.push_back(uint32_t(i));
        power.push_back(std::max(double(l.power()), 0.0));
    }
    if (m_lights.empty()) return;
    double total = 0.0;
    for (double p : power) total += p;
    if (!(total > 0.0)) std::fill(power.begin(), power.end(), 1.0);
    m_dist = DiscreteDistribution(power);
    m_active = true;
}

float CausticLightTracing::camera_density(const Vec3& p_lens, const Vec3& p, const Vec3& ng) const {
    Vec3 w = p - p_lens;
    const float d2 = length_squared(w);
    if (!(d2 > 0.f)) return 0.f;
    w = w / std::sqrt(d2);
    return m_importance.pdf_dir(p_lens, w) * std::fabs(dot(ng, w)) / d2;
}

float CausticLightTracing::light_density(uint32_t light_index, const Vec3& y, const Vec3& toward) const {
    const int32_t slot = light_index < m_slot.size() ? m_slot[light_index] : -1;
    if (slot < 0) return 0.f;
    Vec3 w = toward - y;
    const float d2 = length_squared(w);
    if (!(d2 > 0.f)) return 0.f;
    w = w / std::sqrt(d2);
    const Light& l = m_scene.light(light_index);
    const float cos_y = std::fabs(dot(l.emitter_normal(y), w));
    const float pdf_w = m_guide.pdf(y, w);
    if (!(cos_y > 0.f) || !(pdf_w > 0.f)) return 0.f;
    float pdf_pos = 0.f, pdf_dir = 0.f;
    l.pdf_le(y, w, &pdf_pos, &pdf_dir);
    return m_dist.pmf(size_t(slot)) * pdf_pos * pdf_w / cos_y;
}

void CausticLightTracing::trace(uint64_t seed, uint32_t pixel, uint32_t sample, bool motion_blur,
                                std::vector<std::pair<Vec2, Spectrum>>& out, uint64_t* rays,
                                uint64_t* shadow_rays) const {
    if (!m_active) return;
    const Philox4x32Key key = seed_key(seed);
    uint32_t dim = 0;
    auto draw = [&] { return philox4x32(pixel_counter(pixel, sample, dim++, RngStream::caustic_light), key); };
    auto unit = [](uint32_t x) { return uint_to_unit_float(x); };

    // The light, the point on it, the caster and the direction toward it.
    const Philox4x32Counter a = draw(), b = draw();
    float pmf = 0.f;
    const size_t slot = m_dist.sample(unit(a[0]), &pmf);
    const uint32_t light_index = m_lights[slot];
    const Light& light = m_scene.light(light_index);
    const LightLeSample les = emission_point(light, Vec2(unit(a[1]), unit(a[2])));
    if (!(les.pdf_pos > 0.f) || !(pmf > 0.f)) return;
    const Vec3 y = les.p;
    const Vec3 w = m_guide.sample(y, unit(a[3]), Vec2(unit(b[0]), unit(b[1])));
    Spectrum le;
    if (!light.le_toward(y, w, &le) || is_black(le)) return;
    // The density the camera side evaluates for the same path (light_density's formula).
    const float a0 = light_density(light_index, y, y + w);
    if (!(a0 > 0.f)) return;
    Spectrum beta = le / a0;  // Le |cos_y| / (pmf pdf_pos pdf_w)
    if (is_black(beta) || !is_finite(beta)) return;
    double ratio = double(a0);  // r's numerator so far, over the camera side's factors
    const Vec3 n_y = light.emitter_normal(y);
    Ray ray(is_black(n_y) ? y : offset_ray_origin(y, n_y, les.error_scale, w), w);
    ray.time = motion_blur ? unit(b[2]) : 0.f;

    Spectrum rr_beta(1.f);
    int vertices = 0;  // scattering vertices so far
    for (;;) {
        const SceneHit hit = m_scene.intersect(ray);
        *rays += 1;
        if (hit.kind != SceneHit::Kind::surface) return;
        const SurfaceInteraction& si = hit.si;
        const Vec3 wo = -normalize(ray.d);
        const Material& mat = m_scene.material(si.material_id);
        const Bsdf bsdf = make_bsdf(mat, si, m_scene.textures());
        const Philox4x32Counter u = draw();
        const BsdfSample bs = bsdf.sample(wo, Vec2(unit(u[0]), unit(u[1])), unit(u[2]), TransportMode::Importance);
        if (!bs.valid()) return;
        const Vec3& ns = bsdf.shading_normal();
        if (bs.pass_through && m_scene.material_passes(si.material_id)) {
            // a crossing, not a vertex (as the path tracer walks through it)
            beta *= bs.f * (std::fabs(dot(bs.wi, ns)) / bs.pdf);
            if (is_black(beta) || !is_finite(beta)) return;
            ray = si.spawn_ray(bs.wi);
            ray.time = motion_blur ? unit(b[2]) : 0.f;
            continue;
        }
        ++vertices;
        // The first vertex must scatter by a Dirac lobe; from the second on, a rough
        // vertex is connected to the lens (it is z1 of a path of `vertices` scattering
        // vertices, which the path tracer makes up to max_depth).
        if (vertices >= 2 && bsdf.has_non_delta()) {
            const Philox4x32Counter ul = draw();
            const Vec3 p_lens =
                m_importance.sample_lens(m_importance.has_lens() ? Vec2(unit(ul[0]), unit(ul[1])) : Vec2(0.f, 0.f));
            Vec3 wl = p_lens - si.p;
            const float d2 = length_squared(wl);
            const float cos_o = std::fabs(dot(wo, si.ng));
            if (d2 > 0.f && cos_o > 0.f) {
                wl = wl / std::sqrt(d2);
                Vec2 pr;
                const float we = m_importance.we(p_lens, -wl, &pr);
                const Spectrum f = we > 0.f ? bsdf.eval(wo, wl, TransportMode::Importance) : Spectrum(0.f);
                if (!is_black(f)) {
                    // importance transport through shading normals (bdpt's scatter)
                    const Spectrum v = beta * f *
                                       (std::fabs(dot(wo, ns)) * std::fabs(dot(wl, si.ng)) / cos_o) *
                                       (we * m_importance.cos_axis(-wl) / (d2 * m_importance.pdf_lens()));
                    // r = ratio / (p_cam(z1) p⊥(z1 → z2)), the camera side's density
                    const float p_cam = camera_density(p_lens, si.p, si.ng);
                    const float cos_wo = std::fabs(dot(wo, ns));
                    const float fwd = cos_wo > 0.f ? bsdf.pdf(wl, wo) / cos_wo : 0.f;
                    const double den = double(p_cam) * double(fwd);
                    const float w_light = den > 0.0 ? 1.f - camera_weight(ratio / den) : 1.f;
                    if (w_light > 0.f && !is_black(v) && is_finite(v)) {
                        Ray sr = si.spawn_ray_to(p_lens);
                        sr.time = ray.time;
                        *shadow_rays += 1;
                        *rays += 1;
                        float pass_pdf = 1.f;
                        const float tr = m_scene.transmittance(sr, &pass_pdf);
                        if (tr > 0.f) out.emplace_back(pr, v * (tr * w_light));
                    }
                }
            }
        }
        if (vertices == 1 && !bs.is_delta) return;  // not a path of the class
        if (vertices >= m_max_depth) return;
        if (!bs.is_delta) {
            // this vertex's factor of r: the light side's density over the camera side's
            const float cos_i = std::fabs(dot(bs.wi, ns)), cos_o = std::fabs(dot(wo, ns));
            const float rev = cos_i > 0.f ? bs.pdf / cos_i : 0.f;
            const float fwd = cos_o > 0.f ? bsdf.pdf(bs.wi, wo) / cos_o : 0.f;
            if (!(rev > 0.f)) return;
            ratio = fwd > 0.f ? ratio * double(rev) / double(fwd) : double(k_infinity);
        }
        const float den = std::fabs(dot(wo, si.ng)) * bs.pdf;
        if (!(den > 0.f)) return;
        const Spectrum factor = bs.f * (std::fabs(dot(wo, ns)) * std::fabs(dot(bs.wi, si.ng)) / den);
        beta *= factor;
        rr_beta *= factor;
        if (is_black(beta) || !is_finite(beta)) return;
        if (vertices >= 3) {
            const float q = std::min(0.95f, max_component(rr_beta));
            if (!(unit(u[3]) < q)) return;
            beta /= q;
            rr_beta /= q;
        }
        ray = si.spawn_ray(bs.wi);
        ray.time = motion_blur ? unit(b[2]) : 0.f;
    }
}

}  // namespace cmlt
