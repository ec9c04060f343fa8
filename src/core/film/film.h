#pragma once
/// \file Film: per-pixel double-precision accumulation of filter-weighted samples.
///
/// Each pixel keeps the weighted running mean (West's update of Welford's: sum_i w_i L_i
/// / sum_i w_i, w the pixel filter's f/pdf of the sample: film/filter.h) and M2 per
/// channel, so the variance of the mean is available as an AOV. Dividing by the weights'
/// sum (as pbrt-v4's film does) instead of the count makes a uniform region exactly its
/// radiance although the tabulated filters' weights are only ~1; with weight 1 (the
/// unit box) it is Welford's mean bit for bit. `add_sample` is not synchronised per pixel: a pixel
/// is owned by one task at a time and its samples arrive in sample-index order, which
/// makes the sums bit-reproducible. Non-finite samples are counted (with the first
/// (pixel, sample) in index order) and dropped, never written.
///
/// The variance of the mean is the samples' spread over their count when the samples are
/// independent. With samples that are not (a low-discrepancy sequence) but come in
/// independent blocks of B consecutive sample indices (PixelSequence::sobol_blocks),
/// set_variance_block(B) makes it the spread of the blocks' weighted means over the
/// number of complete blocks (the same weighted Welford update, one block at a time);
/// the mean is the samples' either way, bit for bit. A block is complete once it has B
/// samples; an unfinished one counts in the mean, not in the variance.
///
/// Each pixel also keeps its largest and its smallest pass value (or, with blocks, block
/// mean; by the sum of the channels; two different passes from the second on) with their
/// weights, so develop() can give the mean without them (a trimmed mean, which one
/// firefly does not inflate and symmetric noise does not bias): the denominator of the
/// relMSE estimate (integrators/common/error_target.h) takes it instead of the mean.
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

    /// Add one sample of pixel (x, y) with filter weight `weight`. Returns false (and
    /// counts it) if not finite.
    bool add_sample(int x, int y, uint32_t sample_index, const Spectrum& L, float weight = 1.f);

    /// Count a non-finite sample of pixel (x, y) that was dropped before it got here
    /// (a splatted source sample: film/pass_splatter.h).
    void count_bad_sample(int x, int y, uint32_t sample_index);

    /// Write mean (H, W, 3) and variance of the mean (H, W, 3) as float32, row 0 on top;
    /// with `robust`, also each pixel's mean without its largest and its smallest pass
    /// (with blocks: the finished blocks' mean without the largest and smallest block), NaN
    /// where it has fewer than three (the estimate then takes another denominator).
    void develop(float* image, float* variance, float* robust = nullptr) const;

    /// Variance from blocks of `block` consecutive sample indices (file comment); 1 (the
    /// default): from the samples. Call before the first sample.
    void set_variance_block(uint32_t block);
    uint32_t variance_block() const { return m_block; }

    uint64_t nan_samples() const { return m_nan_count.load(); }
    /// First bad sample in (pixel, sample) order, or false if none.
    bool first_nan(int* x, int* y, uint32_t* sample) const;

private:
    struct Pixel {
        uint32_t n = 0;
        double w = 0;  ///< sum of the weights
        double mean[3] = {0, 0, 0};
        double m2[3] = {0, 0, 0};
        float top[3] = {0, 0, 0}, bot[3] = {0, 0, 0};  ///< the largest and smallest pass value
        float top_w = 0, bot_w = 0;                     ///< their weights (file comment)
    };
    /// A pixel's blocks (set_variance_block): the unfinished one's weighted sums, and the
    /// weighted Welford state over the finished ones' means.
    struct Blocks {
        uint32_t current = ~0u;  ///< block index of the latest block (none: ~0)
        uint32_t n_cur = 0;      ///< its samples so far
        uint32_t n = 0;          ///< blocks before it (finished)
        double w_cur = 0, sum_cur[3] = {0, 0, 0};
        double w = 0, mean[3] = {0, 0, 0}, m2[3] = {0, 0, 0};
        /// the largest and smallest finished block's mean, their weights
        double top[3] = {0, 0, 0}, top_w = 0, bot[3] = {0, 0, 0}, bot_w = 0;
    };
    static void finish_block(Blocks& b);
    /// Track the largest and smallest value of a pixel (or its blocks) after its n-th.
    template <class T, class V>
    static void track_extremes(uint32_t n, const V* v, double w, T* top, T& top_w, T* bot, T& bot_w);
    int m_width, m_height;
    uint32_t m_block = 1;
    std::vector<Pixel> m_pixels;
    std::vector<Blocks> m_blocks;  ///< per pixel, with m_block > 1
    std::atomic<uint64_t> m_nan_count{0};
    std::atomic<uint64_t> m_first_nan_key{~uint64_t(0)};  ///< pixel << 32 | sample
};

}  // namespace cmlt
