#pragma once
/// \file An emissive mesh triangle (world space), two-sided, sampled uniformly by area.
///
/// Emission of UsdPreviewSurface is not culled by winding (and meshes are often
/// doubleSided), so both faces emit.
#include "lights/light.h"
#include "textures/texture.h"

#include <cstdint>

namespace cmlt {

class TriangleLight final : public Light {
public:
    TriangleLight(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Spectrum& le,
                  uint32_t instance_id, uint32_t prim_id);
    LightSample sample_li(const Vec3& p, const Vec2& u) const override;
    /// Intersects the triangle along wi (Moller-Trumbore); used when only a direction is known.
    float pdf_li(const Vec3& p, const Vec3& wi) const override;
    /// Pdf of sampling point q (known to be on the triangle) from p, per solid angle.
    float pdf_li_point(const Vec3& p, const Vec3& q) const;
    float power() const override;
    LightLeSample sample_le(const Vec2& u_pos, const Vec2& u_dir) const override;
    void pdf_le(const Vec3& p, const Vec3& d, float* pdf_pos, float* pdf_dir) const override;
    Vec3 emitter_normal(const Vec3& p) const override;
    bool le_toward(const Vec3& p, const Vec3& d, Spectrum* le) const override;
    float area() const { return m_area; }
    /// Textured emission (emissiveColor from a texture): radiance = tex(st) at the sampled
    /// point, st interpolated from the vertices' uvs. `tex` must outlive the light.
    void set_texture(const Texture* tex, const Vec2& st0, const Vec2& st1, const Vec2& st2);

    /// Emitted radiance at barycentrics (b1, b2) of (p1, p2): the texture at the
    /// interpolated st when textured, else the constant.
    Spectrum radiance_at(const Vec2& b) const;

private:
    Vec3 m_p0, m_e1, m_e2, m_n;
    float m_area = 0.f;
    float m_error_scale = 0.f;
    Spectrum m_le;
    const Texture* m_tex = nullptr;
    Vec2 m_st0, m_st1, m_st2;
    uint32_t m_instance_id, m_prim_id;
};

}  // namespace cmlt
