// Texture lookups (UsdUVTexture): the st transform (UsdTransform2d, folded into a 2x3
// matrix by the Python reader) is applied before wrapping; identity leaves eval alone;
// a non-finite transform is refused naming the texture; the bilinear lookup is the
// weighted sum of its four wrapped texels, for every wrap mode and channel count.
#include "textures/texture.h"
#include "util/error.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

using namespace cmlt;

namespace {

// 2x2 texels, one channel: row 0 (top) = 1, 2; row 1 (bottom) = 3, 4.
TextureDesc quad_desc(WrapMode wrap) {
    auto img = std::make_shared<std::vector<float>>(std::vector<float>{1.f, 2.f, 3.f, 4.f});
    TextureDesc d;
    d.data = img->data();
    d.width = d.height = 2;
    d.channels = 1;
    d.wrap_s = d.wrap_t = wrap;
    d.owner = img;
    return d;
}

}  // namespace

TEST(Texture, IdentityStTransformIsAPlainLookup) {
    Texture t(quad_desc(WrapMode::repeat), "quad");
    EXPECT_FLOAT_EQ(t.eval(Vec2(0.25f, 0.25f)).x, 3.f);  // bottom-left texel
    EXPECT_FLOAT_EQ(t.eval(Vec2(0.75f, 0.75f)).x, 2.f);  // top-right texel
}

TEST(Texture, StTransformAppliesBeforeWrapping) {
    TextureDesc d = quad_desc(WrapMode::repeat);
    const float shift[6] = {1.f, 0.f, 0.5f, 0.f, 1.f, 0.f};  // s + 0.5
    std::copy(shift, shift + 6, d.st_transform);
    Texture t(d, "shifted");
    EXPECT_FLOAT_EQ(t.eval(Vec2(0.25f, 0.25f)).x, 4.f);  // lands on the bottom-right texel
    EXPECT_FLOAT_EQ(t.eval(Vec2(0.75f, 0.25f)).x, 3.f);  // wraps round to bottom-left

    TextureDesc b = quad_desc(WrapMode::black);
    std::copy(shift, shift + 6, b.st_transform);
    Texture tb(b, "shifted black");
    EXPECT_FLOAT_EQ(tb.eval(Vec2(0.75f, 0.25f)).x, 0.f);  // off the edge: black

    TextureDesc r = quad_desc(WrapMode::repeat);
    const float rot90[6] = {0.f, -1.f, 1.f, 1.f, 0.f, 0.f};  // CCW 90 degrees, then s + 1
    std::copy(rot90, rot90 + 6, r.st_transform);
    Texture tr(r, "rotated");
    // (0.25, 0.75) -> (-0.75 + 1, 0.25) = (0.25, 0.25): the bottom-left texel
    EXPECT_FLOAT_EQ(tr.eval(Vec2(0.25f, 0.75f)).x, 3.f);
}

TEST(Texture, NonFiniteStTransformIsRefused) {
    TextureDesc d = quad_desc(WrapMode::repeat);
    d.st_transform[4] = std::numeric_limits<float>::infinity();
    try {
        Texture t(d, "bad xf");
        FAIL() << "no exception";
    } catch (const SceneError& e) {
        EXPECT_NE(std::string(e.what()).find("bad xf: st_transform must be finite"),
                  std::string::npos);
    }
}

namespace {

/// The lookup by its definition: texel centres at integer + 1/2, row 0 at t = 1, the
/// four texels around the point weighted bilinearly (a zero weight or a black-wrapped
/// texel adds nothing), each wrapped on its own, then scale and bias.
float reference_channel(const std::vector<float>& img, int w, int h, int c, WrapMode mode, const Vec2& st,
                        int channel) {
    auto wrap = [&](int v, int n, bool* black) {
        *black = false;
        switch (mode) {
            case WrapMode::repeat: return ((v % n) + n) % n;
            case WrapMode::mirror: {
                int m = ((v % (2 * n)) + 2 * n) % (2 * n);
                return m < n ? m : 2 * n - 1 - m;
            }
            case WrapMode::clamp: return std::min(std::max(v, 0), n - 1);
            case WrapMode::black: *black = v < 0 || v >= n; return v;
        }
        return v;
    };
    const float fx = st.x * float(w) - 0.5f, fy = (1.f - st.y) * float(h) - 0.5f;
    const float x0 = std::floor(fx), y0 = std::floor(fy);
    const float ax = fx - x0, ay = fy - y0;
    float acc = 0.f;
    for (int dy = 0; dy < 2; ++dy)
        for (int dx = 0; dx < 2; ++dx) {
            const float k = (dx ? ax : 1.f - ax) * (dy ? ay : 1.f - ay);
            bool bx, by;
            const int x = wrap(int(x0) + dx, w, &bx), y = wrap(int(y0) + dy, h, &by);
            if (k == 0.f || bx || by) continue;
            const float* p = &img[(size_t(y) * size_t(w) + size_t(x)) * size_t(c)];
            const float rgba[4] = {p[0], c >= 3 ? p[1] : p[0], c >= 3 ? p[2] : p[0],
                                   c == 2 ? p[1] : (c == 4 ? p[3] : 1.f)};
            acc = acc + k * rgba[channel];
        }
    return acc;
}

}  // namespace

TEST(Texture, BilinearLookupIsTheWeightedSumOfItsWrappedTexels) {
    const int w = 5, h = 3;
    uint32_t state = 12345u;
    auto next = [&] {  // a small LCG: values in [0, 1)
        state = state * 1664525u + 1013904223u;
        return float(state >> 8) / float(1u << 24);
    };
    for (int c = 1; c <= 4; ++c)
        for (WrapMode mode : {WrapMode::repeat, WrapMode::mirror, WrapMode::clamp, WrapMode::black}) {
            auto img = std::make_shared<std::vector<float>>(size_t(w * h * c));
            for (float& v : *img) v = next() * 4.f - 1.f;
            TextureDesc d;
            d.data = img->data();
            d.width = w;
            d.height = h;
            d.channels = c;
            d.wrap_s = d.wrap_t = mode;
            d.scale = Vec4(2.f, 1.f, 0.5f, 1.f);
            d.bias = Vec4(0.f, 0.25f, 0.f, -1.f);
            d.owner = img;
            Texture t(d, "random");
            for (int i = 0; i < 4000; ++i) {
                // st over [-3, 4): every side of the image, texel centres and edges included
                Vec2 st(next() * 7.f - 3.f, next() * 7.f - 3.f);
                if (i % 4 == 0) st = Vec2((float(int(next() * 30.f)) + 0.5f) / float(w) - 2.f, st.y);
                if (i % 7 == 0) st = Vec2(st.x, float(int(next() * 20.f) - 8) / float(h));
                const Vec4 got = t.eval(st);
                const float scale[4] = {2.f, 1.f, 0.5f, 1.f}, bias[4] = {0.f, 0.25f, 0.f, -1.f};
                for (int k = 0; k < 4; ++k) {
                    const float want = reference_channel(*img, w, h, c, mode, st, k) * scale[k] + bias[k];
                    ASSERT_EQ(channel_of(got, k), want)
                        << "channels " << c << ", wrap " << int(mode) << ", st (" << st.x << ", " << st.y
                        << "), channel " << k;
                }
            }
        }
}
