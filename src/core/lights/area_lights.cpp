#include "lights/area_lights.h"

#include "math/safe_math.h"
#include "sampling/warp.h"
#include "textures/texture.h"

#include <algorithm>
#include <cmath>

namespace cmlt {

PlanarLight::PlanarLight(const LightDesc& desc, const char* what)
    : m_xf(desc.transform, what), m_radiance(desc.radiance) {
    m_n_emit = normalize(m_xf.normal.transform_normal(Vec3(0.f, 0.f, -1.f)));
    Vec3 zneg = m_xf.m.transform_vector(Vec3(0.f, 0.f, -1.f));
    float lz = length(zneg);
    m_shaping = Shaping(lz > 0.f ? zneg / lz : m_n_emit, desc.cone_angle, desc.cone_softness,
                        desc.focus, desc.focus_tint);
    m_is_analytic_area = true;
}

LightSample PlanarLight::sample_li(const Vec3& p, const Vec2& u) const {
    LightSample s;
    if (!(m_area > 0.f)) return s;
    Vec2 l = sample_local(u);
    Vec3 q = m_xf.m.transform_affine_point(Vec3(l.x, l.y, 0.f));  // m is affine (Transform)
    Vec3 d = q - p;
    float dist2 = length_squared(d);
    if (!(dist2 > 0.f)) return s;
    float dist = std::sqrt(dist2);
    Vec3 wi = d / dist;
    float cos_l = -dot(m_n_emit, wi);  // emitting side faces p when > 0
    if (!(cos_l > 0.f)) return s;
    s.pdf = dist2 / (cos_l * m_area);
    if (!std::isfinite(s.pdf)) return LightSample();
    s.wi = wi;
    s.li = radiance_at(l.x, l.y) * m_shaping.eval(-wi);
    s.dist = dist;
    s.p_light = q;
    return s;
}

bool PlanarLight::intersect(const Ray& ray, float* t, Spectrum* le) const {
    if (!(m_area > 0.f)) return false;
    Vec3 o = m_xf.inv.transform_point(ray.o);
    Vec3 d = m_xf.inv.transform_vector(ray.d);
    // The emitting side is local -Z: a ray sees it while travelling toward +Z.
    if (!(d.z > 0.f)) return false;
    float th = -o.z / d.z;
    if (!(th > ray.tnear && th < ray.tfar)) return false;
    if (!inside(o.x + th * d.x, o.y + th * d.y)) return false;
    *t = th;
    *le = radiance_at(o.x + th * d.x, o.y + th * d.y) * m_shaping.eval(-normalize(ray.d));
    return true;
}

bool PlanarLight::bounding_sphere(Vec3* center, float* radius) const {
    const Vec2 e = local_half_extent();
    *center = m_xf.m.transform_point(Vec3(0.f));
    float r = 0.f;
    for (float sx : {-1.f, 1.f})
        for (float sy : {-1.f, 1.f})
            r = std::max(r, length(m_xf.m.transform_point(Vec3(sx * e.x, sy * e.y, 0.f)) - *center));
    *radius = r;
    return std::isfinite(r);
}

bool PlanarLight::bounding_box(Vec3* lo, Vec3* hi) const {
    const Vec2 e = local_half_extent();
    *lo = Vec3(k_infinity);
    *hi = Vec3(-k_infinity);
    for (float sx : {-1.f, 1.f})
        for (float sy : {-1.f, 1.f}) {
            const Vec3 q = m_xf.m.transform_point(Vec3(sx * e.x, sy * e.y, 0.f));
            *lo = vmin(*lo, q);
            *hi = vmax(*hi, q);
        }
    return is_finite(*lo) && is_finite(*hi);
}

float PlanarLight::pdf_li(const Vec3& p, const Vec3& wi) const {
    float t;
    Spectrum le;
    if (!intersect(Ray(p, wi), &t, &le)) return 0.f;
    float cos_l = -dot(m_n_emit, wi);
    if (!(cos_l > 0.f)) return 0.f;
    float pdf = t * t * length_squared(wi) / (cos_l * m_area);
    return std::isfinite(pdf) ? pdf : 0.f;
}

float PlanarLight::power() const {
    return k_pi * m_area * luminance(m_radiance) * m_shaping.power_factor(true);
}

Spectrum PlanarLight::radiance_at(float x, float y) const {
    if (!m_tex) return m_radiance;
    Vec3 c = m_tex->eval(Vec2(0.5f - x * m_inv_w, 0.5f - y * m_inv_h)).xyz();
    return Spectrum(std::max(0.f, c.x), std::max(0.f, c.y), std::max(0.f, c.z)) * m_radiance;
}

static float parallelogram_area(const Mat4& m, float a, float b) {
    Vec3 ex = m.transform_vector(Vec3(a, 0.f, 0.f));
    Vec3 ey = m.transform_vector(Vec3(0.f, b, 0.f));
    return length(cross(ex, ey));
}

RectLight::RectLight(const LightDesc& desc)
    : PlanarLight(desc, "rect light"), m_w(desc.width), m_h(desc.height) {
    m_texture_id = desc.texture_id;
    m_area = (m_w > 0.f && m_h > 0.f) ? parallelogram_area(m_xf.m, m_w, m_h) : 0.f;
}
void RectLight::bind_texture(const Texture* tex) {
    m_tex = (tex && tex->valid() && m_w > 0.f && m_h > 0.f) ? tex : nullptr;
    m_inv_w = m_w > 0.f ? 1.f / m_w : 0.f;
    m_inv_h = m_h > 0.f ? 1.f / m_h : 0.f;
}

float RectLight::power() const {
    if (!m_tex) return PlanarLight::power();
    Vec3 c = m_tex->mean().xyz();
    Spectrum m(std::max(0.f, c.x), std::max(0.f, c.y), std::max(0.f, c.z));
    return k_pi * m_area * luminance(m * m_radiance) * m_shaping.power_factor(true);
}

bool RectLight::rect_constants(RectLightConstants* out) const {
    if (m_tex || m_shaping.active || !(m_area > 0.f) || is_black(m_radiance)) return false;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) out->m[r][c] = m_xf.m.m[r][c];
    out->w = m_w;
    out->h = m_h;
    out->n_emit = m_n_emit;
    out->area = m_area;
    out->radiance = m_radiance;
    return true;
}

bool RectLight::inside(float x, float y) const {
    return std::fabs(x) <= 0.5f * m_w && std::fabs(y) <= 0.5f * m_h;
}
Vec2 RectLight::sample_local(const Vec2& u) const {
    return {(u.x - 0.5f) * m_w, (u.y - 0.5f) * m_h};
}

DiskLight::DiskLight(const LightDesc& desc) : PlanarLight(desc, "disk light"), m_r(desc.radius) {
    m_area = m_r > 0.f ? k_pi * parallelogram_area(m_xf.m, m_r, m_r) : 0.f;
}
bool DiskLight::inside(float x, float y) const { return x * x + y * y <= m_r * m_r; }
Vec2 DiskLight::sample_local(const Vec2& u) const {
    Vec2 d = square_to_uniform_disk_concentric(u);
    return {d.x * m_r, d.y * m_r};
}

}  // namespace cmlt
