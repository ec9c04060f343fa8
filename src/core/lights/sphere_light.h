#pragma once
/// \file UsdLux SphereLight: sampled by the solid angle of its cone from outside;
/// `treat_as_point` makes it a Dirac point light of intensity L * pi * r^2 (the
/// intensity of the sphere seen from afar). Emits outward only; from inside it is dark.
/// Non-uniform scale is approximated by the radius times cbrt(|det|).
#include "lights/light.h"
#include "lights/shaping.h"

namespace cmlt {

class SphereLight final : public Light {
public:
    explicit SphereLight(const LightDesc& desc);
    LightSample sample_li(const Vec3& p, const Vec2& u) const override;
    bool sphere_constants(SphereLightConstants* out) const override;
    float pdf_li(const Vec3& p, const Vec3& wi) const override;
    bool intersect(const Ray& ray, float* t, Spectrum* le) const override;
    float power() const override;
    LightLeSample sample_le(const Vec2& u_pos, const Vec2& u_dir) const override;
    void pdf_le(const Vec3& p, const Vec3& d, float* pdf_pos, float* pdf_dir) const override;
    Vec3 emitter_normal(const Vec3& p) const override;
    bool le_toward(const Vec3& p, const Vec3& d, Spectrum* le) const override;
    bool bounding_sphere(Vec3* center, float* radius) const override {
        *center = m_center;
        *radius = m_radius;
        return true;
    }

private:
    bool hit_sphere(const Vec3& o, const Vec3& d, float* t) const;
    Vec3 m_center;
    float m_radius = 0.f;
    Spectrum m_radiance;
    bool m_point = false;
    Shaping m_shaping;  ///< UsdLux ShapingAPI (lights/shaping.h)
};

}  // namespace cmlt
