// Emission aimed at the casters; see emission_guide.h.
#include "lights/emission_guide.h"

#include "analysis/scene_probes.h"
#include "lights/light.h"
#include "math/frame.h"
#include "math/safe_math.h"
#include "sampling/warp.h"
#include "scene/scene.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace cmlt {

namespace {

/// More casters than this are guided to as one sphere around them all (pdf loops over
/// the casters at every evaluation).
constexpr size_t k_max_casters = 64;

}  // namespace

bool emission_guidable(const Light& light) {
    if (light.is_delta() || light.is_infinite()) return false;
    // le_toward's answer says whether it is implemented, whatever the point and direction
    Spectrum le;
    return light.le_toward(Vec3(0.f), Vec3(0.f, 0.f, 1.f), &le);
}

LightLeSample emission_point(const Light& light, const Vec2& u_pos) {
    return light.sample_le(u_pos, Vec2(0.25f, 0.25f));
}

EmissionGuide::EmissionGuide(const Scene& scene) {
    std::vector<uint8_t> specular(scene.material_count());
    for (size_t k = 0; k < specular.size(); ++k)
        specular[k] = material_may_be_specular(scene.material(uint32_t(k))) ? 1 : 0;
    Vec3 all_lo(k_infinity), all_hi(-k_infinity);
    for (size_t i = 0; i < scene.instance_count(); ++i) {
        const Instance& inst = scene.instance(uint32_t(i));
        const Mesh& mesh = scene.mesh(inst.mesh_id);
        bool caster = false;
        if (!mesh.data.material_ids) {
            caster = mesh.data.material_id_all < specular.size() && specular[mesh.data.material_id_all];
        } else {
            for (size_t t = 0; t < mesh.data.n_tris && !caster; ++t) {
                const uint32_t m = mesh.data.material_ids[t];
                caster = m < specular.size() && specular[m];
            }
        }
        if (!caster) continue;
        Vec3 lo(k_infinity), hi(-k_infinity);
        for (int c = 0; c < 8; ++c) {
            const Vec3 corner((c & 1) ? mesh.bbox_max.x : mesh.bbox_min.x, (c & 2) ? mesh.bbox_max.y : mesh.bbox_min.y,
                              (c & 4) ? mesh.bbox_max.z : mesh.bbox_min.z);
            const Vec3 p = inst.xf.m.transform_point(corner);
            lo = vmin(lo, p);
            hi = vmax(hi, p);
        }
        if (!is_finite(lo) || !is_finite(hi)) continue;
        all_lo = vmin(all_lo, lo);
        all_hi = vmax(all_hi, hi);
        // a little larger than the box: a grazing ray at the sphere's rim still hits
        m_casters.push_back({(lo + hi) * 0.5f, 0.5f * length(hi - lo) * 1.001f + 1e-6f});
    }
    if (m_casters.size() > k_max_casters)
        m_casters = {{(all_lo + all_hi) * 0.5f, 0.5f * length(all_hi - all_lo) * 1.001f + 1e-6f}};
}

float EmissionGuide::pdf(const Vec3& y, const Vec3& w) const {
    if (m_casters.empty()) return 0.f;
    double sum = 0.0;
    for (const Caster& c : m_casters) {
        const Vec3 d = c.center - y;
        const float dist2 = length_squared(d);
        const float r2 = c.radius * c.radius;
        if (!(dist2 > r2)) {
            sum += k_inv_4pi;  // inside the sphere: every direction
            continue;
        }
        const float dist = std::sqrt(dist2);
        const float sin2 = r2 / dist2;
        const float cos_max = std::sqrt(std::max(0.f, 1.f - sin2));
        if (dot(w, d) < cos_max * dist) continue;
        // 1 - cos_max without cancellation for small cones
        const float one_minus_cos = sin2 / (1.f + cos_max);
        sum += 1.0 / (2.0 * k_pi * double(one_minus_cos));
    }
    return float(sum / double(m_casters.size()));
}

Vec3 EmissionGuide::sample(const Vec3& y, float u_caster, const Vec2& u) const {
    const size_t k = std::min(size_t(u_caster * float(m_casters.size())), m_casters.size() - 1);
    const Caster& c = m_casters[k];
    const Vec3 to_c = c.center - y;
    const float dist2 = length_squared(to_c);
    if (!(dist2 > c.radius * c.radius)) return square_to_uniform_sphere(u);
    const float sin2 = c.radius * c.radius / dist2;
    const float one_minus_cos = sin2 / (1.f + std::sqrt(std::max(0.f, 1.f - sin2)));
    return normalize(Frame(to_c / std::sqrt(dist2)).to_world(square_to_uniform_cone(u, one_minus_cos)));
}

Vec3 EmissionGuide::sample(const Vec3& y, const Vec2& u) const {
    const float scaled = u.x * float(m_casters.size());
    const float k = std::min(std::floor(scaled), float(m_casters.size() - 1));
    const float u0 = std::min(scaled - k, k_one_minus_eps);
    return sample(y, (k + 0.5f) / float(m_casters.size()), Vec2(u0, u.y));
}

double EmissionGuide::coverage(const Vec3& y) const {
    double sum = 0.0;
    for (const Caster& c : m_casters) {
        const double dist2 = double(length_squared(c.center - y)), r2 = double(c.radius) * double(c.radius);
        if (!(dist2 > r2)) return 1.0;  // inside a caster's sphere: every direction
        const double sin2 = r2 / dist2;
        sum += 0.5 * sin2 / (1.0 + std::sqrt(1.0 - sin2));  // (1 - cos θ) / 2 without cancellation
    }
    return std::min(sum, 1.0);
}

double caster_coverage(const Scene& scene, const EmissionGuide& guide) {
    if (!guide.active()) return 0.0;
    double weighted = 0.0, weight = 0.0;
    for (size_t i = 0; i < scene.light_count(); ++i) {
        const Light& light = scene.light(i);
        if (!emission_guidable(light)) continue;
        const double pmf = double(scene.light_pmf(i));
        if (!(pmf > 0.0)) continue;
        const LightLeSample ls = emission_point(light, Vec2(0.5f, 0.5f));
        if (!is_finite(ls.p)) continue;
        weighted += pmf * guide.coverage(ls.p);
        weight += pmf;
    }
    return weight > 0.0 ? weighted / weight : 0.0;
}

}  // namespace cmlt
