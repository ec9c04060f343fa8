#include "lights/cylinder_light.h"

#include "math/frame.h"
#include "math/safe_math.h"
#include "sampling/warp.h"

#include <algorithm>
#include <cmath>

namespace cmlt {

CylinderLight::CylinderLight(const LightDesc& desc) : m_radiance(desc.radiance) {
    Transform xf(desc.transform, "cylinder light");
    m_center = xf.m.transform_point(Vec3(0.f));
    Vec3 ax = xf.m.transform_vector(Vec3(1.f, 0.f, 0.f));
    float sx = length(ax);
    float sy = length(xf.m.transform_vector(Vec3(0.f, 1.f, 0.f)));
    float sz = length(xf.m.transform_vector(Vec3(0.f, 0.f, 1.f)));
    m_axis = sx > 0.f ? ax / sx : Vec3(1.f, 0.f, 0.f);
    Frame f(m_axis);
    m_u = f.s;
    m_v = f.t;
    m_radius = std::max(0.f, desc.radius) * 0.5f * (sy + sz);
    m_length = std::max(0.f, desc.length) * sx;
    m_area = 2.f * k_pi * m_radius * m_length;
    if (!std::isfinite(m_area) || !(m_radius > 0.f) || !(m_length > 0.f)) m_area = 0.f;
    Vec3 zneg = xf.m.transform_vector(Vec3(0.f, 0.f, -1.f));
    float lz = length(zneg);
    m_shaping = Shaping(lz > 0.f ? zneg / lz : Vec3(0.f, 0.f, -1.f), desc.cone_angle,
                        desc.cone_softness, desc.focus, desc.focus_tint);
    m_is_analytic_area = true;
}

void CylinderLight::sample_side(const Vec2& u, Vec3* q, Vec3* n) const {
    float x = (u.x - 0.5f) * m_length;
    float phi = 2.f * k_pi * u.y;
    *n = m_u * std::cos(phi) + m_v * std::sin(phi);
    *q = m_center + m_axis * x + *n * m_radius;
}

bool CylinderLight::hit_side(const Vec3& o, const Vec3& d, float tnear, float tfar,
                             float* t, float* cos_l) const {
    // Entering root of the infinite cylinder from outside, in double; then the length.
    Vec3 oc = o - m_center;
    double ox = double(dot(oc, m_axis)), dx = double(dot(d, m_axis));
    double ou = dot(oc, m_u), ov = dot(oc, m_v), du = dot(d, m_u), dv = dot(d, m_v);
    double a = du * du + dv * dv;
    double b = ou * du + ov * dv;
    double c = ou * ou + ov * ov - double(m_radius) * m_radius;
    if (c <= 0.0 || a <= 0.0) return false;  // inside the infinite cylinder: back side only
    double disc = b * b - a * c;
    if (disc < 0.0) return false;
    double q = -b - std::sqrt(disc);
    if (q <= 0.0) return false;
    double th = q / a;
    if (!(th > tnear && th < tfar)) return false;
    double x = ox + th * dx;
    if (std::fabs(x) > 0.5 * double(m_length)) return false;  // open end: caps do not emit
    *t = float(th);
    // Cosine at the outward normal, -dot(n, d / |d|) = sqrt(disc) / (r |d|): exact at
    // grazing angles, where the hit point's normal would not be.
    if (cos_l) {
        double dd = std::sqrt(a + dx * dx);
        *cos_l = float(std::sqrt(disc) / (double(m_radius) * dd));
    }
    return true;
}

LightSample CylinderLight::sample_li(const Vec3& p, const Vec2& u) const {
    LightSample s;
    if (!(m_area > 0.f)) return s;
    Vec3 q, n;
    sample_side(u, &q, &n);
    Vec3 d = q - p;
    float dist2 = length_squared(d);
    if (!(dist2 > 0.f)) return s;
    float dist = std::sqrt(dist2);
    Vec3 wi = d / dist;
    float cos_l = -dot(n, wi);
    if (!(cos_l > 0.f)) return s;
    s.pdf = dist2 / (cos_l * m_area);
    if (!std::isfinite(s.pdf)) return LightSample();
    s.wi = wi;
    s.li = m_radiance * m_shaping.eval(-wi);
    s.dist = dist;
    s.p_light = q;
    s.n_light = n;
    s.error_scale = m_radius;
    return s;
}

float CylinderLight::pdf_li(const Vec3& p, const Vec3& wi) const {
    if (!(m_area > 0.f)) return 0.f;
    float t;
    float cos_l;
    if (!hit_side(p, wi, 0.f, k_infinity, &t, &cos_l)) return 0.f;
    float l2 = length_squared(wi);
    if (!(cos_l > 0.f)) return 0.f;
    float pdf = t * t * l2 / (cos_l * m_area);
    return std::isfinite(pdf) ? pdf : 0.f;
}

bool CylinderLight::intersect(const Ray& ray, float* t, Spectrum* le) const {
    if (!(m_area > 0.f)) return false;
    float th;
    if (!hit_side(ray.o, ray.d, ray.tnear, ray.tfar, &th, nullptr)) return false;
    *t = th;
    *le = m_radiance * m_shaping.eval(-normalize(ray.d));
    return true;
}

float CylinderLight::power() const {
    return k_pi * m_area * luminance(m_radiance) * m_shaping.power_factor(false);
}

// Emission sampling (BDPT, MLT): uniform by area, cosine about the outward normal.
LightLeSample CylinderLight::sample_le(const Vec2& u_pos, const Vec2& u_dir) const {
    LightLeSample s;
    if (!(m_area > 0.f)) return s;
    Vec3 q, n;
    sample_side(u_pos, &q, &n);
    s.p = q;
    s.n = n;
    Vec3 local = square_to_cosine_hemisphere(u_dir);
    s.d = normalize(Frame(n).to_world(local));
    s.pdf_pos = 1.f / m_area;
    s.pdf_dir = local.z * k_inv_pi;
    s.le = m_radiance * m_shaping.eval(s.d);
    s.error_scale = std::max(max_component(vabs(q)), m_radius);
    if (!(s.pdf_dir > 0.f) || !std::isfinite(s.pdf_pos)) return LightLeSample();
    return s;
}

void CylinderLight::pdf_le(const Vec3& p, const Vec3& d, float* pdf_pos, float* pdf_dir) const {
    *pdf_pos = *pdf_dir = 0.f;
    if (!(m_area > 0.f)) return;
    float c = dot(emitter_normal(p), d);
    *pdf_pos = 1.f / m_area;
    *pdf_dir = c > 0.f ? c * k_inv_pi : 0.f;
}

bool CylinderLight::le_toward(const Vec3& p, const Vec3& d, Spectrum* le) const {
    *le = Spectrum(0.f);
    if (dot(emitter_normal(p), d) > 0.f) *le = m_radiance * m_shaping.eval(d);
    return true;
}

Vec3 CylinderLight::emitter_normal(const Vec3& p) const {
    Vec3 r = p - m_center;
    r = r - m_axis * dot(r, m_axis);
    float l = length(r);
    return l > 0.f && std::isfinite(l) ? r / l : m_u;
}

}  // namespace cmlt
