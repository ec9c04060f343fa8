#pragma once
/// \file Splat film of the Metropolis integrators (pssmlt, cmlt: integrators/mlt's frame
/// owns one): per-pixel sums of weighted colours, accumulated in 128-bit fixed point (32
/// fractional bits) with atomic integer adds.
///
/// Why fixed point: integer addition is exact and commutative, so the sum does not
/// depend on the order in which chains running on different threads splat — the image
/// is bit-identical for any thread count, with one shared buffer (per-chain double
/// films would cost chains × image memory; per-thread ones depend on the scheduling).
/// The resolution, 2^-32 ≈ 2.3e-10 per splat, is finer than a double's relative
/// precision at the sums reached (the DESIGN.md §2 concern: float sums drift at high
/// sample counts). A single splat beyond ±2^30 is clamped and counted.
///
/// Range: one int64 word would hold ±2^31 per pixel and channel, which a bright pixel
/// passes at high mutation counts (10^6 under the pixel importance at 4,000 mutations per
/// pixel; the luminance target's L/Y of a saturated colour over 10^8 splats) — and wrap
/// around silently. So each sum is a 128-bit two's-complement integer in two words:
/// `lo` (unsigned, the fixed-point value mod 2^64) gets every splat q with fetch_add, and
/// the carry out of that add (known exactly from the value fetch_add returns) plus q's
/// sign extension go to `hi`. Each carry belongs to one add in lo's modification order,
/// so the pair sums exactly whatever the order; hi is touched only when lo wraps (a sum
/// crossing a multiple of 2^32 in value units or changing sign), so the common path is one
/// atomic add as before, and sums inside the old range read back bit-identically.
#include "film/filter.h"
#include "math/vec.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

namespace cmlt {

class SplatFilm {
public:
    static constexpr double k_scale = 4294967296.0;  ///< 2^32: one unit of the sum
    static constexpr double k_max_splat = 1073741824.0;  ///< 2^30

    /// `layers` >= 1 separate sums (the error groups: a chain splats into its group's
    /// layer); sum() adds them up exactly, so the image does not depend on the count.
    SplatFilm(int width, int height, int layers = 1)
        : m_width(width), m_height(height), m_layers(std::max(layers, 1)),
          m_lo(new std::atomic<uint64_t>[size_t(width) * height * 3 * size_t(std::max(layers, 1))]),
          m_hi(new std::atomic<int64_t>[size_t(width) * height * 3 * size_t(std::max(layers, 1))]) {
        for (size_t i = 0, n = size_t(width) * height * 3 * size_t(m_layers); i < n; ++i) {
            m_lo[i].store(0, std::memory_order_relaxed);
            m_hi[i].store(0, std::memory_order_relaxed);
        }
    }

    int width() const { return m_width; }
    int height() const { return m_height; }
    int layers() const { return m_layers; }

    /// Add `weight · colour` to pixel `pixel` (= y·W + x). Thread-safe; order-independent.
    void add(uint32_t pixel, const Spectrum& colour, double weight, int layer = 0) {
        const float c[3] = {colour.x, colour.y, colour.z};
        for (int k = 0; k < 3; ++k) {
            double v = double(c[k]) * weight;
            if (!(v == v)) continue;  // NaN never reaches the film (callers check)
            if (std::fabs(v) > k_max_splat) {
                v = v > 0 ? k_max_splat : -k_max_splat;
                m_clamped.fetch_add(1, std::memory_order_relaxed);
            }
            const int64_t q = round_half_away(v * k_scale);
            if (q == 0) continue;
            const size_t i = (size_t(layer) * size_t(m_width) * size_t(m_height) + pixel) * 3 + k;
            const uint64_t uq = uint64_t(q);
            const uint64_t old = m_lo[i].fetch_add(uq, std::memory_order_relaxed);
            // 128-bit add of sign-extended q: hi gets the carry out of lo, minus 1 for q < 0
            const int64_t dh = int64_t(old + uq < old) - int64_t(q < 0);
            if (dh != 0) m_hi[i].fetch_add(dh, std::memory_order_relaxed);
        }
    }

    /// Sum of pixel i, channel k over every layer, as a double.
    double sum(size_t i, int k) const {
        __int128 v = 0;
        for (int l = 0; l < m_layers; ++l) v += word(l, i, k);  // exact: wraps as the one sum would
        return double(v) / k_scale;  // rounds once, as the one-word conversion did
    }
    /// Sum of pixel i, channel k in one layer.
    double layer_sum(int layer, size_t i, int k) const { return double(word(layer, i, k)) / k_scale; }
    uint64_t clamped() const { return m_clamped.load(); }

    /// The raw sums over every layer: low and high words of every pixel and channel
    /// (W·H·3 each; the layers' exact 128-bit sum, as sum() develops it).
    void export_words(std::vector<uint64_t>& lo, std::vector<int64_t>& hi) const {
        const size_t n = size_t(m_width) * m_height * 3;
        lo.resize(n);
        hi.resize(n);
        for (size_t j = 0; j < n; ++j) {
            unsigned __int128 v = 0;
            for (int l = 0; l < m_layers; ++l) v += (unsigned __int128)word(l, j / 3, int(j % 3));
            lo[j] = uint64_t(v);
            hi[j] = int64_t(uint64_t(v >> 64));
        }
    }
    /// Add another film's raw sums (export_words), exactly: 128-bit integer adds, so
    /// films of disjoint sets of splats sum to the film that received them all.
    /// They go into layer 0 (a combined film keeps no groups).
    void add_words(const uint64_t* lo, const int64_t* hi) {
        for (size_t i = 0, n = size_t(m_width) * m_height * 3; i < n; ++i) {
            const uint64_t old = m_lo[i].fetch_add(lo[i], std::memory_order_relaxed);
            const int64_t dh = hi[i] + int64_t(old + lo[i] < old);
            if (dh != 0) m_hi[i].fetch_add(dh, std::memory_order_relaxed);
        }
    }

    /// Add `weight · colour` over `filter`'s footprint around film position p (weights
    /// f(c - p), film/filter.h); the unit box: add(pixel, ...) to the pixel given.
    void add_filtered(const PixelFilter& filter, const Vec2& p, uint32_t pixel, const Spectrum& colour,
                      double weight, int layer = 0) {
        if (filter.unit_box()) {
            add(pixel, colour, weight, layer);
            return;
        }
        filter.footprint(p, m_width, m_height, [&](uint32_t j, double w) { add(j, colour, weight * w, layer); });
    }

    /// std::llround of x for |x| < 2^63 (here at most 2^62), inline instead of a libm
    /// call: the truncation and the remainder are exact, so is the rounding (half away
    /// from zero).
    static int64_t round_half_away(double x) {
        int64_t q = int64_t(x);
        const double r = x - double(q);
        q += int64_t(r >= 0.5) - int64_t(r <= -0.5);
        return q;
    }

private:
    __int128 word(int layer, size_t i, int k) const {
        const size_t j = (size_t(layer) * size_t(m_width) * size_t(m_height) + i) * 3 + size_t(k);
        const unsigned __int128 lo = m_lo[j].load(std::memory_order_relaxed);
        return __int128((unsigned __int128)(m_hi[j].load(std::memory_order_relaxed)) << 64 | lo);
    }

    int m_width, m_height, m_layers;
    std::unique_ptr<std::atomic<uint64_t>[]> m_lo;  ///< fixed-point sums mod 2^64
    std::unique_ptr<std::atomic<int64_t>[]> m_hi;   ///< their high words (carries, signs)
    std::atomic<uint64_t> m_clamped{0};
};

}  // namespace cmlt
