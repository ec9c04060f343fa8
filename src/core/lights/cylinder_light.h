#pragma once
/// \file UsdLux CylinderLight: the side of a cylinder along local X (length `length`,
/// radius `radius`, centred on the origin) emitting outward; the caps do not emit and,
/// as for every analytic light, the cylinder does not block rays. Seen from inside
/// (through an open end) it is dark. Sampled uniformly by area over the side (back-facing
/// samples are rejected), converted to solid angle. `treat_as_point` (treatAsLine, a hint
/// in UsdLux) is ignored: the light stays a cylinder of its radius. The transform is
/// expected rigid (cmlt.usd); a scale is approximated: length times |X axis|, radius
/// times the mean of |Y axis| and |Z axis|.
#include "lights/light.h"
#include "lights/shaping.h"

#include <cmath>

namespace cmlt {

class CylinderLight final : public Light {
public:
    explicit CylinderLight(const LightDesc& desc);
    LightSample sample_li(const Vec3& p, const Vec2& u) const override;
    float pdf_li(const Vec3& p, const Vec3& wi) const override;
    bool intersect(const Ray& ray, float* t, Spectrum* le) const override;
    float power() const override;
    LightLeSample sample_le(const Vec2& u_pos, const Vec2& u_dir) const override;
    void pdf_le(const Vec3& p, const Vec3& d, float* pdf_pos, float* pdf_dir) const override;
    Vec3 emitter_normal(const Vec3& p) const override;
    bool le_toward(const Vec3& p, const Vec3& d, Spectrum* le) const override;
    float area() const { return m_area; }
    bool bounding_sphere(Vec3* center, float* radius) const override {
        *center = m_center;
        *radius = std::sqrt(0.25f * m_length * m_length + m_radius * m_radius);
        return std::isfinite(*radius);
    }

private:
    /// World point and outward normal for u in [0,1)^2 (x along the axis, angle).
    void sample_side(const Vec2& u, Vec3* q, Vec3* n) const;
    bool hit_side(const Vec3& o, const Vec3& d, float tnear, float tfar, float* t,
                  float* cos_l) const;
    Vec3 m_center, m_axis, m_u, m_v;  ///< world centre, unit axis (local X), radial frame
    float m_radius = 0.f, m_length = 0.f, m_area = 0.f;
    Spectrum m_radiance;
    Shaping m_shaping;
};

}  // namespace cmlt
