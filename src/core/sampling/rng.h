#pragma once
/// \file Counter-based random numbers: Philox-4x32-10 (Salmon et al. 2011, "Parallel
/// random numbers: as easy as 1, 2, 3").
///
/// A value is a pure function of (key, counter): there is no sequential state, so
/// results do not depend on thread count or scheduling. Samplers key the counter by
/// (pixel index, sample index, dimension, stream) and the key by the seed.
#include <array>
#include <cstdint>

#include "math/safe_math.h"
#include "math/vec.h"

namespace cmlt {

using Philox4x32Counter = std::array<uint32_t, 4>;
using Philox4x32Key = std::array<uint32_t, 2>;

/// Philox-4x32 with 10 rounds.
inline Philox4x32Counter philox4x32(Philox4x32Counter c, Philox4x32Key k) {
    constexpr uint32_t M0 = 0xD2511F53u, M1 = 0xCD9E8D57u;
    constexpr uint32_t W0 = 0x9E3779B9u, W1 = 0xBB67AE85u;
    for (int round = 0; round < 10; ++round) {
        uint64_t p0 = uint64_t(M0) * c[0];
        uint64_t p1 = uint64_t(M1) * c[2];
        uint32_t hi0 = uint32_t(p0 >> 32), lo0 = uint32_t(p0);
        uint32_t hi1 = uint32_t(p1 >> 32), lo1 = uint32_t(p1);
        c = {hi1 ^ c[1] ^ k[0], lo1, hi0 ^ c[3] ^ k[1], lo0};
        k[0] += W0;
        k[1] += W1;
    }
    return c;
}

/// uint32 -> float in [0, 1) (top 24 bits; exactly representable, never 1).
inline float uint_to_unit_float(uint32_t v) { return float(v >> 8) * 0x1p-24f; }

/// Stream ids: separate counter spaces for different consumers.
enum class RngStream : uint32_t { camera_path = 0, light_path = 1, test = 0xFFFF };

/// Random numbers of one pixel sample: dimension d of (seed, pixel, sample, stream).
/// `get1d`/`get2d` consume dimensions in order; `set_dimension` jumps to a fixed
/// dimension so that e.g. each bounce owns a fixed dimension range.
class PixelSampler {
public:
    PixelSampler(uint64_t seed, uint32_t pixel, uint32_t sample,
                 RngStream stream = RngStream::camera_path)
        : m_key{uint32_t(seed), uint32_t(seed >> 32)},
          m_pixel(pixel), m_sample(sample), m_stream(uint32_t(stream)) {}

    void set_dimension(uint32_t d) { m_dim = d; }
    uint32_t dimension() const { return m_dim; }

    float get1d() { return uint_to_unit_float(draw()[0]); }
    Vec2 get2d() {
        Philox4x32Counter r = draw();
        return {uint_to_unit_float(r[0]), uint_to_unit_float(r[1])};
    }
    /// Raw 4x32 bits of the next dimension.
    Philox4x32Counter get_bits() { return draw(); }

private:
    Philox4x32Counter draw() {
        return philox4x32({m_pixel, m_sample, m_dim++, m_stream}, m_key);
    }
    Philox4x32Key m_key;
    uint32_t m_pixel, m_sample, m_stream;
    uint32_t m_dim = 0;
};

}  // namespace cmlt
