#pragma once
/// \file UsdLux DistantLight (and, through dome_light.h, DomeLight).
///
/// DistantLight: light travels toward local -Z, so the direction *to* the light is local
/// +Z. `angle` is the angular diameter in degrees. angle > 0: a cone of directions with
/// radiance `radiance`, sampled uniformly in the cone and seen by escaping rays inside
/// it. angle == 0: a Dirac direction; `radiance` is then read as the irradiance on a
/// surface facing the light (the limit of a normalised distant light).
///
/// DomeLight: lights/dome_light.h (constant or lat-long textured).
#include "lights/dome_light.h"
#include "lights/light.h"

namespace cmlt {

class DistantLight final : public Light {
public:
    explicit DistantLight(const LightDesc& desc);
    LightSample sample_li(const Vec3& p, const Vec2& u) const override;
    float pdf_li(const Vec3& p, const Vec3& wi) const override;
    Spectrum le_escape(const Vec3& d) const override;
    void preprocess(const Vec3& center, float radius) override { m_scene_radius = radius; }
    float power() const override;

private:
    Vec3 m_axis;              ///< unit direction toward the light
    Spectrum m_radiance;
    float m_one_minus_cos = 0.f;
    float m_scene_radius = 1.f;
};


}  // namespace cmlt
