#pragma once
/// \file Image textures (UsdUVTexture): a float32 (H, W, C) image shared with its owner
/// (a numpy array, zero copy) plus the sampler state of the USD node.
///
/// Conventions:
///  - Texels are already in the rendering space (ACEScg), or raw (normal maps, scalars);
///    the Python side converts them once at load time.
///  - Row 0 is the *top* of the image (OpenImageIO order); st = (0, 0) is the bottom-left
///    corner, as UsdUVTexture specifies, so t is flipped when addressing rows.
///  - Filtering is bilinear on the full-resolution image (no mip chain yet: minified textures
///    alias, which only adds variance, never bias, at the sample counts we use).
///  - Output = texel * scale + bias (per channel, UsdUVTexture's inputs:scale / inputs:bias).
///    A 1- or 2-channel image returns (r, r, r) as rgb; a missing alpha is 1 (before scale
///    and bias).
///  - Wrap modes follow UsdUVTexture: repeat, mirror, clamp, black (outside [0, 1] -> 0,
///    then scale and bias are applied to 0 like any texel).
///  - `st_transform`: an affine map applied to st before the lookup, the texture's
///    UsdTransform2d (st' = in * scale * rotate + translation, folded into a 2x3 matrix
///    by the Python reader); identity by default.
#include "math/vec.h"

#include <cstdint>
#include <memory>

namespace cmlt {

enum class WrapMode : uint8_t { repeat, mirror, clamp, black };

struct TextureDesc {
    const float* data = nullptr;  ///< (height, width, channels), C-contiguous
    int width = 0, height = 0, channels = 0;
    WrapMode wrap_s = WrapMode::repeat, wrap_t = WrapMode::repeat;
    Vec4 scale{1.f, 1.f, 1.f, 1.f};
    Vec4 bias{0.f, 0.f, 0.f, 0.f};
    /// st' = (m[0] s + m[1] t + m[2], m[3] s + m[4] t + m[5]) before the lookup.
    float st_transform[6] = {1.f, 0.f, 0.f, 0.f, 1.f, 0.f};
    std::shared_ptr<void> owner;  ///< keeps `data` alive
};

class Texture {
public:
    Texture() = default;
    /// Throws SceneError naming `name` on bad sizes or non-finite texels.
    Texture(TextureDesc desc, const char* name = "texture");

    bool valid() const { return m_d.data != nullptr; }
    int width() const { return m_d.width; }
    int height() const { return m_d.height; }
    int channels() const { return m_d.channels; }

    /// Bilinear lookup at st (UsdUVTexture convention) after `st_transform`, scale and
    /// bias applied.
    Vec4 eval(const Vec2& st) const;
    /// Raw texel (x right, y down from the top row), rgba as described above, no scale/bias.
    Vec4 texel(int x, int y) const {
        return rgba(m_d.data + (size_t(y) * size_t(m_d.width) + size_t(x)) * size_t(m_d.channels), m_d.channels);
    }
    /// Mean texel with scale and bias applied (light power estimates).
    Vec4 mean() const { return scale_bias(m_mean); }
    /// Apply the node's scale and bias.
    Vec4 scale_bias(const Vec4& v) const {
        return {v.x * m_d.scale.x + m_d.bias.x, v.y * m_d.scale.y + m_d.bias.y,
                v.z * m_d.scale.z + m_d.bias.z, v.w * m_d.scale.w + m_d.bias.w};
    }

private:
    /// The rgba of the texel at `p` with `channels` channels.
    static Vec4 rgba(const float* p, int channels) {
        switch (channels) {
            case 1: return {p[0], p[0], p[0], 1.f};
            case 2: return {p[0], p[0], p[0], p[1]};
            case 3: return {p[0], p[1], p[2], 1.f};
            default: return {p[0], p[1], p[2], p[3]};
        }
    }
    /// Wrap an integer texel coordinate; false if the texel is black (WrapMode::black).
    /// Inside the image every mode keeps it (inline); outside: wrap_outside.
    static bool wrap(int* i, int n, WrapMode mode) {
        return unsigned(*i) < unsigned(n) || wrap_outside(i, n, mode);
    }
    static bool wrap_outside(int* i, int n, WrapMode mode);

    TextureDesc m_d;
    Vec4 m_mean;
    bool m_st_identity = true;
};

/// Component `channel` (0..3) of an rgba value.
inline float channel_of(const Vec4& v, int channel) {
    switch (channel) {
        case 0: return v.x;
        case 1: return v.y;
        case 2: return v.z;
        default: return v.w;
    }
}

}  // namespace cmlt
