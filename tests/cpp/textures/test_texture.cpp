// Texture lookups (UsdUVTexture): the st transform (UsdTransform2d, folded into a 2x3
// matrix by the Python reader) is applied before wrapping; identity leaves eval alone;
// a non-finite transform is refused naming the texture.
#include "textures/texture.h"
#include "util/error.h"

#include <gtest/gtest.h>

#include <algorithm>
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
