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

bool Texture::wrap_outside(int* i, int n, WrapMode mode) {
    int v = *i;
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

namespace {

/// floor(v) for |v| <= 2^24 (every such float's integer neighbours are floats): the
/// same value as std::floor there without the libm call (x86-64's baseline has no
/// rounding instruction).
inline float floor_in_range(float v) {
    const float t = float(int(v));  // toward zero
    return t > v ? t - 1.f : t;
}

}  // namespace

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
    // Keep the integer part in range of int for huge st (repeat is periodic anyway); fx
    // and fy are not NaN here, so comparisons clamp as fmin / fmax would (without their
    // libm calls).
    const float lim = 1 << 24;
    fx = fx < -lim ? -lim : (fx > lim ? lim : fx);
    fy = fy < -lim ? -lim : (fy > lim ? lim : fy);
    const float x0f = floor_in_range(fx), y0f = floor_in_range(fy);
    const float ax = fx - x0f, ay = fy - y0f;
    const float wx[2] = {1.f - ax, ax}, wy[2] = {1.f - ay, ay};
    // The two columns and rows of the 2x2 footprint, wrapped (false: a black texel).
    int xs[2] = {int(x0f), int(x0f) + 1}, ys[2] = {int(y0f), int(y0f) + 1};
    bool in_x[2], in_y[2];
    for (int k = 0; k < 2; ++k) {
        in_x[k] = wrap(&xs[k], m_d.width, m_d.wrap_s);
        in_y[k] = wrap(&ys[k], m_d.height, m_d.wrap_t);
    }
    const size_t w = size_t(m_d.width), c = size_t(m_d.channels);
    Vec4 acc;
    for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
            const float k = wx[dx] * wy[dy];
            if (k == 0.f || !in_x[dx] || !in_y[dy]) continue;
            const Vec4 t = rgba(m_d.data + (size_t(ys[dy]) * w + size_t(xs[dx])) * c, m_d.channels);
            acc = {acc.x + k * t.x, acc.y + k * t.y, acc.z + k * t.z, acc.w + k * t.w};
        }
    return scale_bias(acc);
}

}  // namespace cmlt
