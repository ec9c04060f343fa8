#pragma once
/// \file UsdLux RectLight and DiskLight: planar, one-sided, emitting toward local -Z.
///
/// RectLight texture (inputs:texture:file): the radiance is multiplied by the texture's
/// rgb at st = (1/2 - x/width, 1/2 - y/height) for the local point (x, y): UsdLux puts
/// the texture's min coordinates at (+X, +Y) and its max at (-X, -Y), so the image reads
/// the right way round seen from the emitting (-Z) side. Sampling stays uniform by area.
#include "lights/light.h"
#include "lights/shaping.h"

namespace cmlt {

/// Planar light in local z = 0 with a shape test; shared by rect and disk.
class PlanarLight : public Light {
public:
    LightSample sample_li(const Vec3& p, const Vec2& u) const override;
    float pdf_li(const Vec3& p, const Vec3& wi) const override;
    bool intersect(const Ray& ray, float* t, Spectrum* le) const override;
    float power() const override;
    float area() const { return m_area; }
    LightLeSample sample_le(const Vec2& u_pos, const Vec2& u_dir) const override;
    void pdf_le(const Vec3& p, const Vec3& d, float* pdf_pos, float* pdf_dir) const override;
    Vec3 emitter_normal(const Vec3& p) const override;
    bool le_toward(const Vec3& p, const Vec3& d, Spectrum* le) const override;
    bool bounding_sphere(Vec3* center, float* radius) const override;
    /// The box of the shape's local rectangle's four corners.
    bool bounding_box(Vec3* lo, Vec3* hi) const override;
    /// Radiance emitted at local point (x, y) (textured rect lights vary).
    Spectrum radiance_at(float x, float y) const;

protected:
    PlanarLight(const LightDesc& desc, const char* what);
    /// Local (x, y) inside the shape?
    virtual bool inside(float x, float y) const = 0;
    /// Map u to a local point in the shape.
    virtual Vec2 sample_local(const Vec2& u) const = 0;
    /// Half extents of a local rectangle containing the shape.
    virtual Vec2 local_half_extent() const = 0;

    Transform m_xf;
    Spectrum m_radiance;
    Vec3 m_n_emit;   ///< unit world normal of the emitting side (local -Z)
    float m_area = 0.f;
    const Texture* m_tex = nullptr;  ///< rect only
    float m_inv_w = 0.f, m_inv_h = 0.f;
    Shaping m_shaping;  ///< UsdLux ShapingAPI (lights/shaping.h)
};

class RectLight final : public PlanarLight {
public:
    explicit RectLight(const LightDesc& desc);
    void bind_texture(const Texture* tex) override;
    float power() const override;
    bool rect_constants(RectLightConstants* out) const override;

protected:
    bool inside(float x, float y) const override;
    Vec2 sample_local(const Vec2& u) const override;
    Vec2 local_half_extent() const override { return {0.5f * m_w, 0.5f * m_h}; }

private:
    float m_w, m_h;
};

class DiskLight final : public PlanarLight {
public:
    explicit DiskLight(const LightDesc& desc);

protected:
    bool inside(float x, float y) const override;
    Vec2 sample_local(const Vec2& u) const override;
    Vec2 local_half_extent() const override { return {m_r, m_r}; }

private:
    float m_r;
};

}  // namespace cmlt
