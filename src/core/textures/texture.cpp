#include "textures/texture.h"

#include "util/error.h"

#include <cmath>

namespace cmlt {

Texture::Texture(TextureDesc desc, const char* name) : m_d(std::move(desc)) {
    if (!m_d.data) CMLT_THROW(SceneError, name << ": no texel data");
    if (m_d.width < 1 || m_d.height < 1 || m_d.channels < 1 || m_d.channels > 4)
        CMLT_THROW(SceneError, name << ": shape must be (H >= 1, W >= 1, 1..4 channels), got ("
                                    << m_d.height << ", " << m_d.width << ", " << m_d.channels << ")");
    size_t n = size_t(m_d.width) * size_t(m_d.height) * size_t(m_d.channels);
    for (size_t i = 0; i < n; ++i)
        if (!std::isfinite(m_d.data[i]))
            CMLT_THROW(SceneError, name << ": texel value " << i << " is NaN or Inf");
    double acc[4] = {0, 0, 0, 0};
    for (int y = 0; y < m_d.height; ++y)
        for (int x = 0; x < m_d.width; ++x) {
            Vec4 t = texel(x, y);
            acc[0] += t.x; acc[1] += t.y; acc[2] += t.z; acc[3] += t.w;
        }
    double inv = 1.0 / (double(m_d.width) * double(m_d.height));
    m_mean = Vec4(float(acc[0] * inv), float(acc[1] * inv), float(acc[2] * inv), float(acc[3] * inv));
    const float* sb[8] = {&m_d.scale.x, &m_d.scale.y, &m_d.scale.z, &m_d.scale.w,
                          &m_d.bias.x,  &m_d.bias.y,  &m_d.bias.z,  &m_d.bias.w};
    for (const float* v : sb)
        if (!std::isfinite(*v)) CMLT_THROW(SceneError, name << ": scale and bias must be finite");
    for (float v : m_d.st_transform)
        if (!std::isfinite(v)) CMLT_THROW(SceneError, name << ": st_transform must be finite");
    const float* m = m_d.st_transform;
    m_st_identity = m[0] == 1.f && m[1] == 0.f && m[2] == 0.f && m[3] == 0.f && m[4] == 1.f &&
                    m[5] == 0.f;
}

bool Texture::wrap(int* i, int n, WrapMode mode) {
    int v = *i;
    if (unsigned(v) < unsigned(n)) return true;  // inside: every mode keeps it (no division)
    switch (mode) {
        case WrapMode::repeat:
            v %= n;
            if (v < 0) v += n;
            break;
        case WrapMode::mirror: {
            int period = 2 * n;
            v %= period;
            if (v < 0) v += period;
            if (v >= n) v = period - 1 - v;
            break;
        }
        case WrapMode::clamp: v = v < 0 ? 0 : (v >= n ? n - 1 : v); break;
        case WrapMode::black:
            if (v < 0 || v >= n) return false;
            break;
    }
    *i = v;
    return true;
}

Vec4 Texture::texel(int x, int y) const {
    const float* p = m_d.data + (size_t(y) * size_t(m_d.width) + size_t(x)) * size_t(m_d.channels);
    switch (m_d.channels) {
        case 1: return {p[0], p[0], p[0], 1.f};
        case 2: return {p[0], p[0], p[0], p[1]};
        case 3: return {p[0], p[1], p[2], 1.f};
        default: return {p[0], p[1], p[2], p[3]};
    }
}

Vec4 Texture::eval(const Vec2& st_in) const {
    if (!valid()) return scale_bias(Vec4());
    Vec2 st = st_in;
    if (!m_st_identity) {
        const float* m = m_d.st_transform;
        st = Vec2(m[0] * st_in.x + m[1] * st_in.y + m[2], m[3] * st_in.x + m[4] * st_in.y + m[5]);
    }
    if (!std::isfinite(st.x) || !std::isfinite(st.y)) return scale_bias(Vec4());
    // Continuous texel coordinates, texel centres at integer + 1/2; row 0 at t = 1.
    float fx = st.x * float(m_d.width) - 0.5f;
    float fy = (1.f - st.y) * float(m_d.height) - 0.5f;
    // Keep the integer part in range of int for huge st (repeat is periodic anyway).
    const float lim = 1 << 24;
    fx = std::fmax(-lim, std::fmin(lim, fx));
    fy = std::fmax(-lim, std::fmin(lim, fy));
    float x0f = std::floor(fx), y0f = std::floor(fy);
    float ax = fx - x0f, ay = fy - y0f;
    int x0 = int(x0f), y0 = int(y0f);
    Vec4 acc;
    for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
            float w = (dx ? ax : 1.f - ax) * (dy ? ay : 1.f - ay);
            if (w == 0.f) continue;
            int x = x0 + dx, y = y0 + dy;
            if (!wrap(&x, m_d.width, m_d.wrap_s) || !wrap(&y, m_d.height, m_d.wrap_t)) continue;
            Vec4 t = texel(x, y);
            acc = {acc.x + w * t.x, acc.y + w * t.y, acc.z + w * t.z, acc.w + w * t.w};
        }
    return scale_bias(acc);
}

}  // namespace cmlt
