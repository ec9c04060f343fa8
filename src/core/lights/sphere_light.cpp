#include "lights/sphere_light.h"

#include "math/frame.h"
#include "math/safe_math.h"
#include "sampling/warp.h"

#include <cmath>

namespace cmlt {

SphereLight::SphereLight(const LightDesc& desc) : m_radiance(desc.radiance) {
    Transform xf(desc.transform, "sphere light");
    m_center = xf.m.transform_point(Vec3(0.f));
    float s = float(std::cbrt(std::fabs(xf.m.determinant())));
    m_radius = std::max(0.f, desc.radius) * s;
    m_point = desc.treat_as_point;
    m_is_delta = m_point;
    m_is_analytic_area = !m_point;
    Vec3 zneg = xf.m.transform_vector(Vec3(0.f, 0.f, -1.f));
    float lz = length(zneg);
    m_shaping = Shaping(lz > 0.f ? zneg / lz : Vec3(0.f, 0.f, -1.f), desc.cone_angle,
                        desc.cone_softness, desc.focus, desc.focus_tint);
}

bool SphereLight::hit_sphere(const Vec3& o, const Vec3& d, float* t) const {
    // Nearest root of |o + t d - c|^2 = r^2 from outside, in double for grazing rays.
    double ocx = double(o.x) - m_center.x, ocy = double(o.y) - m_center.y,
           ocz = double(o.z) - m_center.z;
    double a = double(d.x) * d.x + double(d.y) * d.y + double(d.z) * d.z;
    double b = ocx * d.x + ocy * d.y + ocz * d.z;
    double c = ocx * ocx + ocy * ocy + ocz * ocz - double(m_radius) * m_radius;
    if (c <= 0.0 || a <= 0.0) return false;  // inside (or on) the sphere: dark
    double disc = b * b - a * c;
    if (disc < 0.0) return false;
    double q = -b - std::sqrt(disc);
    if (q <= 0.0) return false;
    *t = float(q / a);
    return true;
}

bool SphereLight::sphere_constants(SphereLightConstants* out) const {
    if (m_point || m_shaping.active || !(m_radius > 0.f) || is_black(m_radiance)) return false;
    out->center = m_center;
    out->radius = m_radius;
    out->radiance = m_radiance;
    return true;
}

LightSample SphereLight::sample_li(const Vec3& p, const Vec2& u) const {
    LightSample s;
    if (!(m_radius > 0.f)) return s;
    Vec3 to_c = m_center - p;
    float dist_c = length(to_c);
    if (m_point) {
        if (!(dist_c > 0.f)) return s;
        s.wi = to_c / dist_c;
        s.li = m_radiance * m_shaping.eval(-s.wi) * (k_pi * m_radius * m_radius / (dist_c * dist_c));
        s.pdf = 1.f;
        s.is_delta = true;
        s.dist = dist_c;
        s.p_light = m_center;
        if (!is_finite(s.li)) return LightSample();
        return s;
    }
    if (!(dist_c > m_radius)) return s;
    float omc = sphere_cone_one_minus_cos(m_radius, dist_c);
    if (!(omc > 0.f)) return s;
    Frame frame(to_c / dist_c);
    Vec3 wi = normalize(frame.to_world(square_to_uniform_cone(u, omc)));
    float t;
    if (!hit_sphere(p, wi, &t)) {
        // Grazing direction at the cone's rim: the tangent point.
        t = dist_c * std::max(0.f, dot(wi, to_c / dist_c));
    }
    s.wi = wi;
    s.li = m_radiance * m_shaping.eval(-wi);
    s.pdf = 1.f / (2.f * k_pi * omc);
    s.dist = t;
    s.p_light = p + wi * t;
    return s;
}

float SphereLight::pdf_li(const Vec3& p, const Vec3& wi) const {
    if (m_point || !(m_radius > 0.f)) return 0.f;
    float dist_c = length(m_center - p);
    if (!(dist_c > m_radius)) return 0.f;
    float t;
    if (!hit_sphere(p, wi, &t)) return 0.f;
    float omc = sphere_cone_one_minus_cos(m_radius, dist_c);
    return omc > 0.f ? 1.f / (2.f * k_pi * omc) : 0.f;
}

bool SphereLight::intersect(const Ray& ray, float* t, Spectrum* le) const {
    if (m_point || !(m_radius > 0.f)) return false;
    float th;
    if (!hit_sphere(ray.o, ray.d, &th)) return false;
    if (!(th > ray.tnear && th < ray.tfar)) return false;
    *t = th;
    *le = m_radiance * m_shaping.eval(-normalize(ray.d));
    return true;
}

float SphereLight::power() const {
    float area = 4.f * k_pi * m_radius * m_radius;
    // Point: 4 pi I with I = L pi r^2 -- the same as the sphere's pi * area * L.
    return k_pi * area * luminance(m_radiance) * m_shaping.power_factor(false);
}

}  // namespace cmlt
