#include "lights/infinite_lights.h"

#include "math/frame.h"
#include "math/safe_math.h"
#include "sampling/warp.h"
#include "util/error.h"

#include <cmath>

namespace cmlt {

DistantLight::DistantLight(const LightDesc& desc) : m_radiance(desc.radiance) {
    Transform xf(desc.transform, "distant light");
    m_axis = normalize(xf.m.transform_vector(Vec3(0.f, 0.f, 1.f)));
    if (!(desc.angle >= 0.f) || !std::isfinite(desc.angle))
        CMLT_THROW(SceneError, "distant light: angle must be finite and >= 0, got " << desc.angle);
    double half = 0.5 * std::min(double(desc.angle), 360.0) * 3.14159265358979323846 / 180.0;
    double s = std::sin(0.5 * half);
    m_one_minus_cos = float(std::min(2.0, 2.0 * s * s));  // 1 - cos(half) without cancellation
    m_is_delta = !(m_one_minus_cos > 0.f);
    m_is_infinite = true;
}

LightSample DistantLight::sample_li(const Vec3&, const Vec2& u) const {
    LightSample s;
    if (m_is_delta) {
        s.wi = m_axis;
        s.li = m_radiance;
        s.pdf = 1.f;
        s.is_delta = true;
        return s;
    }
    Frame f(m_axis);
    s.wi = normalize(f.to_world(square_to_uniform_cone(u, m_one_minus_cos)));
    s.li = m_radiance;
    s.pdf = 1.f / (2.f * k_pi * m_one_minus_cos);
    return s;
}

float DistantLight::pdf_li(const Vec3&, const Vec3& wi) const {
    if (m_is_delta) return 0.f;
    Frame f(m_axis);
    return square_to_uniform_cone_pdf(f.to_local(wi), m_one_minus_cos);
}

Spectrum DistantLight::le_escape(const Vec3& d) const {
    if (m_is_delta) return Spectrum(0.f);
    Frame f(m_axis);
    return square_to_uniform_cone_pdf(f.to_local(normalize(d)), m_one_minus_cos) > 0.f
               ? m_radiance
               : Spectrum(0.f);
}

float DistantLight::power() const {
    float irradiance = m_is_delta ? luminance(m_radiance)
                                  : luminance(m_radiance) * 2.f * k_pi * m_one_minus_cos;
    return k_pi * m_scene_radius * m_scene_radius * irradiance;
}

}  // namespace cmlt
