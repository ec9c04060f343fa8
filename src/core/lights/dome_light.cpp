#include "lights/dome_light.h"

#include "math/safe_math.h"
#include "sampling/warp.h"
#include "textures/texture.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace cmlt {

namespace {
constexpr float k_two_pi_sq = 2.f * k_pi * k_pi;
}

Vec2 dome_direction_to_st(const Vec3& d) {
    float phi = std::atan2(d.x, d.z);
    float theta = std::acos(std::clamp(d.y, -1.f, 1.f));
    float s = 0.5f - phi * (0.5f * k_inv_pi);
    if (s >= 1.f) s -= 1.f;
    if (s < 0.f) s += 1.f;
    return {s, 1.f - theta * k_inv_pi};
}

Vec3 dome_st_to_direction(const Vec2& st, float* sin_theta) {
    float phi = k_pi * (1.f - 2.f * st.x);
    float theta = k_pi * (1.f - st.y);
    float st_ = std::sin(theta);
    *sin_theta = st_;
    return {st_ * std::sin(phi), std::cos(theta), st_ * std::cos(phi)};
}

DomeLight::DomeLight(const LightDesc& desc)
    : m_xf(desc.transform, "dome light"), m_radiance(desc.radiance) {
    m_is_infinite = true;
    m_texture_id = desc.texture_id;
}

void DomeLight::bind_texture(const Texture* tex) {
    m_tex = (tex && tex->valid()) ? tex : nullptr;
    m_dist = PiecewiseConstant2D();
    m_integral = 0.f;
    if (!m_tex) return;
    const int w = m_tex->width(), h = m_tex->height();
    std::vector<float> lum(size_t(w) * size_t(h));
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            Vec3 c = m_tex->scale_bias(m_tex->texel(x, y)).xyz();
            Spectrum l(std::max(0.f, c.x), std::max(0.f, c.y), std::max(0.f, c.z));
            lum[size_t(y) * w + x] = std::max(0.f, luminance(l * m_radiance));
        }
    std::vector<float> wts(lum.size());
    double sum = 0.0, integral = 0.0;
    for (int y = 0; y < h; ++y) {
        float sin_c = std::sin(k_pi * (float(y) + 0.5f) / float(h));
        for (int x = 0; x < w; ++x) {
            float m = 0.f;
            for (int dy = -1; dy <= 1; ++dy) {
                int yy = std::clamp(y + dy, 0, h - 1);
                for (int dx = -1; dx <= 1; ++dx) {
                    int xx = ((x + dx) % w + w) % w;
                    m = std::max(m, lum[size_t(yy) * w + xx]);
                }
            }
            wts[size_t(y) * w + x] = m * sin_c;
            sum += double(m * sin_c);
            integral += double(lum[size_t(y) * w + x]) * sin_c;
        }
    }
    float floor = float(1e-4 * sum / double(wts.size()));
    if (!(floor > 0.f)) floor = 1.f;  // black texture: uniform over (s, v)
    for (float& v : wts) v += floor;
    m_dist = PiecewiseConstant2D(wts, w, h);
    m_integral = float(integral * double(k_two_pi_sq) / (double(w) * double(h)));
}

Spectrum DomeLight::lookup(const Vec2& st) const {
    Vec3 c = m_tex->eval(st).xyz();
    return Spectrum(std::max(0.f, c.x), std::max(0.f, c.y), std::max(0.f, c.z)) * m_radiance;
}

LightSample DomeLight::sample_li(const Vec3&, const Vec2& u) const {
    LightSample s;
    if (!m_tex) {
        s.wi = square_to_uniform_sphere(u);
        s.li = m_radiance;
        s.pdf = k_inv_4pi;
        return s;
    }
    float pdf2 = 0.f;
    Vec2 sv = m_dist.sample(u, &pdf2);  // (s, v), v = 1 - t: rows from the top
    if (!(pdf2 > 0.f)) return s;
    Vec2 st(sv.x, 1.f - sv.y);
    float sin_theta = 0.f;
    Vec3 local = dome_st_to_direction(st, &sin_theta);
    if (!(sin_theta > 0.f)) return s;
    s.wi = normalize(m_xf.m.transform_vector(local));
    s.pdf = pdf2 / (k_two_pi_sq * sin_theta);
    s.li = lookup(st);
    if (!std::isfinite(s.pdf) || !is_finite(s.wi)) return LightSample();
    return s;
}

float DomeLight::texture_pdf(const Vec3& local, const Vec2& st) const {
    float sin_theta = std::sqrt(std::max(0.f, 1.f - local.y * local.y));
    if (!(sin_theta > 0.f)) return 0.f;
    float pdf = m_dist.pdf(Vec2(st.x, 1.f - st.y)) / (k_two_pi_sq * sin_theta);
    return std::isfinite(pdf) ? pdf : 0.f;
}

float DomeLight::pdf_li(const Vec3&, const Vec3& wi) const {
    if (!m_tex) return k_inv_4pi;
    Vec3 local = normalize(m_xf.inv.transform_vector(wi));
    return texture_pdf(local, dome_direction_to_st(local));
}

Spectrum DomeLight::le_escape(const Vec3& d) const { return le_escape_pdf(d, Vec3(0.f), nullptr); }

Spectrum DomeLight::le_escape_pdf(const Vec3& d, const Vec3& p, float* pdf) const {
    if (!m_tex) {
        if (pdf) *pdf = pdf_li(p, d);
        return m_radiance;
    }
    Vec3 local = normalize(m_xf.inv.transform_vector(d));
    const Vec2 st = dome_direction_to_st(local);
    if (pdf) *pdf = texture_pdf(local, st);
    return lookup(st);
}

float DomeLight::power() const {
    float integral = m_tex ? m_integral : 4.f * k_pi * luminance(m_radiance);
    return k_pi * m_scene_radius * m_scene_radius * integral;
}

}  // namespace cmlt
