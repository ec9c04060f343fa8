#pragma once
/// \file Film: per-pixel double-precision accumulation with a box filter.
///
/// Each pixel keeps Welford's running mean and M2 per channel, so the sample variance of
/// the mean is available as an AOV. `add_sample` is not synchronised per pixel: a pixel
/// is owned by one task at a time and its samples arrive in sample-index order, which
/// makes the sums bit-reproducible. Non-finite samples are counted (with the first
/// (pixel, sample) in index order) and dropped, never written.
#include "math/vec.h"

#include <atomic>
#include <cstdint>
#include <vector>

namespace cmlt {

class Film {
public:
    Film(int width, int height);

    int width() const { return m_width; }
    int height() const { return m_height; }

    /// Add one sample of pixel (x, y). Returns false (and counts it) if not finite.
    bool add_sample(int x, int y, uint32_t sample_index, const Spectrum& L);

    /// Write mean (H, W, 3) and variance of the mean (H, W, 3) as float32, row 0 on top.
    void develop(float* image, float* variance) const;

    uint64_t nan_samples() const { return m_nan_count.load(); }
    /// First bad sample in (pixel, sample) order, or false if none.
    bool first_nan(int* x, int* y, uint32_t* sample) const;

private:
    struct Pixel {
        uint32_t n = 0;
        double mean[3] = {0, 0, 0};
        double m2[3] = {0, 0, 0};
    };
    int m_width, m_height;
    std::vector<Pixel> m_pixels;
    std::atomic<uint64_t> m_nan_count{0};
    std::atomic<uint64_t> m_first_nan_key{~uint64_t(0)};  ///< pixel << 32 | sample
};

}  // namespace cmlt
