#pragma once
/// \file Splat film of the Metropolis integrators: per-pixel sums of weighted colours,
/// accumulated in 64-bit fixed point (32 fractional bits) with atomic integer adds.
///
/// Why fixed point: integer addition is exact and commutative, so the sum does not
/// depend on the order in which chains running on different threads splat — the image
/// is bit-identical for any thread count, with one shared buffer (per-chain double
/// films would cost chains × image memory; per-thread ones depend on the scheduling).
/// The resolution, 2^-32 ≈ 2.3e-10 per splat, is finer than a double's relative
/// precision at the sums reached (the DESIGN.md §2 concern: float sums drift at high
/// sample counts); the range, ±2^31 per pixel and channel, holds e.g. 10^7 mutations per
/// pixel of splats up to 100. A single splat beyond ±2^30 is clamped and counted.
#include "math/vec.h"

#include <atomic>
#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

namespace cmlt::mlt {

class SplatFilm {
public:
    static constexpr double k_scale = 4294967296.0;  ///< 2^32: one unit of the sum
    static constexpr double k_max_splat = 1073741824.0;  ///< 2^30

    SplatFilm(int width, int height)
        : m_width(width), m_height(height), m_sums(new std::atomic<int64_t>[size_t(width) * height * 3]) {
        for (size_t i = 0, n = size_t(width) * height * 3; i < n; ++i) m_sums[i].store(0, std::memory_order_relaxed);
    }

    int width() const { return m_width; }
    int height() const { return m_height; }

    /// Add `weight · colour` to pixel `pixel` (= y·W + x). Thread-safe; order-independent.
    void add(uint32_t pixel, const Spectrum& colour, double weight) {
        const float c[3] = {colour.x, colour.y, colour.z};
        for (int k = 0; k < 3; ++k) {
            double v = double(c[k]) * weight;
            if (!(v == v)) continue;  // NaN never reaches the film (callers check)
            if (std::fabs(v) > k_max_splat) {
                v = v > 0 ? k_max_splat : -k_max_splat;
                m_clamped.fetch_add(1, std::memory_order_relaxed);
            }
            const int64_t q = std::llround(v * k_scale);
            if (q != 0) m_sums[size_t(pixel) * 3 + k].fetch_add(q, std::memory_order_relaxed);
        }
    }

    /// Sum of pixel i, channel k, as a double.
    double sum(size_t i, int k) const {
        return double(m_sums[i * 3 + k].load(std::memory_order_relaxed)) / k_scale;
    }
    uint64_t clamped() const { return m_clamped.load(); }

private:
    int m_width, m_height;
    std::unique_ptr<std::atomic<int64_t>[]> m_sums;
    std::atomic<uint64_t> m_clamped{0};
};

}  // namespace cmlt::mlt
