#pragma once
/// \file UsdLux DomeLight: constant or lat-long textured radiance from every direction.
///
/// Radiance: `radiance` (intensity * 2^exposure * color) times the texture's rgb (ACEScg,
/// after the UsdUVTexture-style scale/bias of the registered texture) when textured.
///
/// Lat-long mapping (UsdLux DomeLight / OpenEXR latlong), in *light space* with +Y the
/// pole: the light's transform (rotation, optionally uniform scale) places it in the
/// world; the default (identity) orientation has the top pole on world +Y, latitude 0
/// longitude 0 along +Z and longitude +pi/2 along +X. With the texture's st (s right,
/// t up; texture row 0 = the top = +Y):
///     phi   = pi (1 - 2 s)        (longitude: +pi at the left edge, -pi at the right)
///     theta = pi (1 - t)          (angle from +Y: 0 at the top row)
///     d     = (sin theta sin phi, cos theta, sin theta cos phi)
/// and back: s = 1/2 - atan2(d.x, d.z) / (2 pi), t = 1 - acos(d.y) / pi. The measure:
/// d(omega) = 2 pi^2 sin(theta) ds dt.
///
/// Sampling: untextured, uniform over the sphere (1 / 4pi). Textured, a 2-D
/// piecewise-constant distribution over the texels (PiecewiseConstant2D, cell (x, row))
/// weighted by luminance x sin(theta at the row centre), where each cell's luminance is
/// the maximum over its 3x3 neighbourhood (so that the bilinear lookup never has
/// radiance where the density is 0) plus a floor of 1e-4 of the mean; the solid-angle
/// density is p(s, v) / (2 pi^2 sin theta), v = 1 - t.
#include "lights/light.h"
#include "sampling/piecewise_constant_2d.h"

namespace cmlt {

class Texture;

/// Light-space unit direction -> texture st (see the file comment).
Vec2 dome_direction_to_st(const Vec3& d);
/// Texture st -> light-space unit direction; *sin_theta receives sin(theta).
Vec3 dome_st_to_direction(const Vec2& st, float* sin_theta);

class DomeLight final : public Light {
public:
    explicit DomeLight(const LightDesc& desc);
    LightSample sample_li(const Vec3& p, const Vec2& u) const override;
    float pdf_li(const Vec3& p, const Vec3& wi) const override;
    Spectrum le_escape(const Vec3& d) const override;
    Spectrum le_escape_pdf(const Vec3& d, const Vec3& p, float* pdf) const override;
    void preprocess(const Vec3& center, float radius) override { m_scene_radius = radius; }
    float power() const override;
    void bind_texture(const Texture* tex) override;
    bool textured() const { return m_tex != nullptr; }

private:
    Spectrum lookup(const Vec2& st) const;
    /// pdf_li of the direction `local` (light space, unit) with texture coordinates `st`.
    float texture_pdf(const Vec3& local, const Vec2& st) const;

    Transform m_xf;
    Spectrum m_radiance;
    const Texture* m_tex = nullptr;
    PiecewiseConstant2D m_dist;
    float m_integral = 0.f;  ///< integral of luminance(L) over the sphere (power)
    float m_scene_radius = 1.f;
};

}  // namespace cmlt
