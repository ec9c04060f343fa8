#include "lights/triangle_light.h"

#include "math/safe_math.h"
#include "sampling/warp.h"
#include "scene/interaction.h"

#include <cmath>

namespace cmlt {

TriangleLight::TriangleLight(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Spectrum& le,
                             uint32_t instance_id, uint32_t prim_id)
    : m_p0(p0), m_e1(p1 - p0), m_e2(p2 - p0), m_le(le), m_instance_id(instance_id),
      m_prim_id(prim_id) {
    Vec3 c = cross(m_e1, m_e2);
    float len = length(c);
    m_area = 0.5f * len;
    m_n = len > 0.f ? c / len : Vec3(0.f);
    m_error_scale = max_component(vmax(vabs(p0), vmax(vabs(p1), vabs(p2))));
}

LightSample TriangleLight::sample_li(const Vec3& p, const Vec2& u) const {
    LightSample s;
    if (!(m_area > 0.f)) return s;
    Vec2 b = square_to_uniform_triangle(u);
    Vec3 q = m_p0 + m_e1 * b.x + m_e2 * b.y;
    Vec3 d = q - p;
    float dist2 = length_squared(d);
    if (!(dist2 > 0.f)) return s;
    float dist = std::sqrt(dist2);
    Vec3 wi = d / dist;
    float cos_l = std::fabs(dot(m_n, wi));
    if (!(cos_l > 0.f)) return s;
    s.pdf = dist2 / (cos_l * m_area);
    if (!std::isfinite(s.pdf)) return LightSample();
    s.wi = wi;
    s.li = radiance_at(b);
    s.dist = dist;
    s.p_light = q;
    s.n_light = m_n;
    s.error_scale = m_error_scale;
    return s;
}

Spectrum TriangleLight::radiance_at(const Vec2& b) const {
    if (!m_tex) return m_le;
    float b0 = 1.f - b.x - b.y;
    Vec2 st(m_st0.x * b0 + m_st1.x * b.x + m_st2.x * b.y,
            m_st0.y * b0 + m_st1.y * b.x + m_st2.y * b.y);
    Vec3 e = m_tex->eval(st).xyz();
    return Spectrum(std::fmax(0.f, e.x), std::fmax(0.f, e.y), std::fmax(0.f, e.z));
}

float TriangleLight::pdf_li_point(const Vec3& p, const Vec3& q) const {
    if (!(m_area > 0.f)) return 0.f;
    Vec3 d = q - p;
    float dist2 = length_squared(d);
    if (!(dist2 > 0.f)) return 0.f;
    float cos_l = std::fabs(dot(m_n, d)) / std::sqrt(dist2);
    if (!(cos_l > 0.f)) return 0.f;
    float pdf = dist2 / (cos_l * m_area);
    return std::isfinite(pdf) ? pdf : 0.f;
}

float TriangleLight::pdf_li(const Vec3& p, const Vec3& wi) const {
    if (!(m_area > 0.f)) return 0.f;
    // Moller-Trumbore.
    Vec3 pv = cross(wi, m_e2);
    float det = dot(m_e1, pv);
    if (det == 0.f) return 0.f;
    float inv = 1.f / det;
    Vec3 tv = p - m_p0;
    float u = dot(tv, pv) * inv;
    if (u < 0.f || u > 1.f) return 0.f;
    Vec3 qv = cross(tv, m_e1);
    float v = dot(wi, qv) * inv;
    if (v < 0.f || u + v > 1.f) return 0.f;
    float t = dot(m_e2, qv) * inv;
    if (!(t > 0.f)) return 0.f;
    return pdf_li_point(p, p + wi * t);
}

void TriangleLight::set_texture(const Texture* tex, const Vec2& st0, const Vec2& st1,
                                const Vec2& st2) {
    m_tex = tex;
    m_st0 = st0;
    m_st1 = st1;
    m_st2 = st2;
    if (tex) {
        Vec3 e = tex->mean().xyz();
        m_le = Spectrum(std::fmax(0.f, e.x), std::fmax(0.f, e.y), std::fmax(0.f, e.z));
    }
}

float TriangleLight::power() const { return 2.f * k_pi * m_area * luminance(m_le); }

}  // namespace cmlt
