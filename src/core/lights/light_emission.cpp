// Emission sampling of the finite lights (light tracing, BDPT, MLT): sample_le, pdf_le,
// emitter_normal. Kept apart from the illumination code (sample_li) of each light file.
//
// Positions are sampled uniformly by area (1/area), directions cosine-weighted about the
// emitting side's normal; two-sided emitters (mesh triangles) pick a side with
// probability 1/2. A point light (sphere with treat_as_point) emits its intensity
// uniformly over the sphere of directions from a Dirac position (pdf_pos = 1).
#include "lights/area_lights.h"
#include "lights/sphere_light.h"
#include "lights/triangle_light.h"

#include "math/frame.h"
#include "math/safe_math.h"
#include "sampling/warp.h"
#include "scene/interaction.h"

#include <cmath>

namespace cmlt {

// ---- rect / disk: one-sided, emit toward local -Z --------------------------------------

LightLeSample PlanarLight::sample_le(const Vec2& u_pos, const Vec2& u_dir) const {
    LightLeSample s;
    if (!(m_area > 0.f)) return s;
    Vec2 l = sample_local(u_pos);
    s.p = m_xf.m.transform_point(Vec3(l.x, l.y, 0.f));
    s.n = m_n_emit;
    Vec3 local = square_to_cosine_hemisphere(u_dir);
    s.d = normalize(Frame(m_n_emit).to_world(local));
    s.pdf_pos = 1.f / m_area;
    s.pdf_dir = local.z * k_inv_pi;
    s.le = radiance_at(l.x, l.y) * m_shaping.eval(s.d);
    s.error_scale = point_error_scale(s.p);
    if (!(s.pdf_dir > 0.f) || !std::isfinite(s.pdf_pos)) return LightLeSample();
    return s;
}

void PlanarLight::pdf_le(const Vec3&, const Vec3& d, float* pdf_pos, float* pdf_dir) const {
    float c = dot(m_n_emit, d);
    *pdf_pos = m_area > 0.f ? 1.f / m_area : 0.f;
    *pdf_dir = c > 0.f ? c * k_inv_pi : 0.f;
}

Vec3 PlanarLight::emitter_normal(const Vec3&) const { return m_n_emit; }

bool PlanarLight::le_toward(const Vec3& p, const Vec3& d, Spectrum* le) const {
    *le = Spectrum(0.f);
    if (dot(m_n_emit, d) > 0.f) {
        const Vec3 l = m_xf.inv.transform_point(p);
        *le = radiance_at(l.x, l.y) * m_shaping.eval(d);
    }
    return true;
}

// ---- sphere (and point) -----------------------------------------------------------------

LightLeSample SphereLight::sample_le(const Vec2& u_pos, const Vec2& u_dir) const {
    LightLeSample s;
    if (!(m_radius > 0.f)) return s;
    if (m_point) {
        s.p = m_center;
        s.d = square_to_uniform_sphere(u_dir);
        s.pdf_pos = 1.f;
        s.pdf_dir = k_inv_4pi;
        s.le = m_radiance * m_shaping.eval(s.d) * (k_pi * m_radius * m_radius);  // intensity
        s.error_scale = point_error_scale(s.p);
        return s;
    }
    Vec3 n = square_to_uniform_sphere(u_pos);
    s.p = m_center + n * m_radius;
    s.n = n;
    Vec3 local = square_to_cosine_hemisphere(u_dir);
    s.d = normalize(Frame(n).to_world(local));
    s.pdf_pos = 1.f / (4.f * k_pi * m_radius * m_radius);
    s.pdf_dir = local.z * k_inv_pi;
    s.le = m_radiance * m_shaping.eval(s.d);
    s.error_scale = point_error_scale(s.p) + m_radius;
    if (!(s.pdf_dir > 0.f) || !std::isfinite(s.pdf_pos)) return LightLeSample();
    return s;
}

void SphereLight::pdf_le(const Vec3& p, const Vec3& d, float* pdf_pos, float* pdf_dir) const {
    *pdf_pos = *pdf_dir = 0.f;
    if (!(m_radius > 0.f)) return;
    if (m_point) {
        *pdf_pos = 1.f;
        *pdf_dir = k_inv_4pi;
        return;
    }
    float c = dot(emitter_normal(p), d);
    *pdf_pos = 1.f / (4.f * k_pi * m_radius * m_radius);
    *pdf_dir = c > 0.f ? c * k_inv_pi : 0.f;
}

bool SphereLight::le_toward(const Vec3& p, const Vec3& d, Spectrum* le) const {
    *le = Spectrum(0.f);
    if (m_point) return false;  // a Dirac position: no camera ray sees it either
    if (dot(emitter_normal(p), d) > 0.f) *le = m_radiance * m_shaping.eval(d);
    return true;
}

Vec3 SphereLight::emitter_normal(const Vec3& p) const {
    if (m_point) return Vec3(0.f);
    Vec3 n = normalize(p - m_center);
    return is_finite(n) ? n : Vec3(0.f, 0.f, 1.f);
}

// ---- mesh triangle: two-sided ------------------------------------------------------------

LightLeSample TriangleLight::sample_le(const Vec2& u_pos, const Vec2& u_dir) const {
    LightLeSample s;
    if (!(m_area > 0.f)) return s;
    Vec2 b = square_to_uniform_triangle(u_pos);
    s.p = m_p0 + m_e1 * b.x + m_e2 * b.y;
    // Pick a side with u_dir.x, then reuse it for the direction.
    Vec2 u = u_dir;
    Vec3 n = m_n;
    if (u.x < 0.5f) {
        u.x = 2.f * u.x;
    } else {
        u.x = clamp_below_one(2.f * u.x - 1.f);
        n = -m_n;
    }
    Vec3 local = square_to_cosine_hemisphere(u);
    s.n = n;
    s.d = normalize(Frame(n).to_world(local));
    s.pdf_pos = 1.f / m_area;
    s.pdf_dir = 0.5f * local.z * k_inv_pi;
    s.le = radiance_at(b);  // textured emission, as sample_li and the camera hits see it
    s.error_scale = m_error_scale;
    if (!(s.pdf_dir > 0.f) || !std::isfinite(s.pdf_pos)) return LightLeSample();
    return s;
}

void TriangleLight::pdf_le(const Vec3&, const Vec3& d, float* pdf_pos, float* pdf_dir) const {
    *pdf_pos = m_area > 0.f ? 1.f / m_area : 0.f;
    *pdf_dir = 0.5f * std::fabs(dot(m_n, d)) * k_inv_pi;
}

Vec3 TriangleLight::emitter_normal(const Vec3&) const { return m_n; }

bool TriangleLight::le_toward(const Vec3& p, const Vec3&, Spectrum* le) const {
    // both faces emit; the barycentrics of p (on the triangle) pick the texel
    const Vec3 v = p - m_p0;
    const float d00 = dot(m_e1, m_e1), d01 = dot(m_e1, m_e2), d11 = dot(m_e2, m_e2);
    const float d20 = dot(v, m_e1), d21 = dot(v, m_e2);
    const float den = d00 * d11 - d01 * d01;
    Vec2 b(1.f / 3.f, 1.f / 3.f);
    if (den > 0.f && std::isfinite(den))
        b = Vec2((d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den);
    *le = radiance_at(b);
    return true;
}

}  // namespace cmlt
