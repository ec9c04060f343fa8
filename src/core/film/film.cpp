#include "film/film.h"

#include "util/error.h"

#include <cmath>

namespace cmlt {

Film::Film(int width, int height)
    : m_width(width), m_height(height), m_pixels(size_t(width) * size_t(height)) {
    CMLT_CHECK(width > 0 && height > 0);
}

bool Film::add_sample(int x, int y, uint32_t sample_index, const Spectrum& L, float weight) {
    size_t idx = size_t(y) * size_t(m_width) + size_t(x);
    if (!is_finite(L) || !std::isfinite(weight)) {
        count_bad_sample(x, y, sample_index);
        return false;
    }
    Pixel& p = m_pixels[idx];
    p.n += 1;
    const double w = double(weight);
    p.w += w;
    if (p.w == 0.0) return true;  // (negative lobes) no mean yet; the next sample gives one
    const double share = w / p.w;  // weight 1: 1 / n, Welford's
    for (int c = 0; c < 3; ++c) {
        double v = double(L[c]);
        double delta = v - p.mean[c];
        p.mean[c] += delta * share;
        p.m2[c] += w * delta * (v - p.mean[c]);
    }
    return true;
}

void Film::count_bad_sample(int x, int y, uint32_t sample_index) {
    const size_t idx = size_t(y) * size_t(m_width) + size_t(x);
    m_nan_count.fetch_add(1, std::memory_order_relaxed);
    const uint64_t key = (uint64_t(idx) << 32) | sample_index;
    uint64_t cur = m_first_nan_key.load(std::memory_order_relaxed);
    while (key < cur && !m_first_nan_key.compare_exchange_weak(cur, key)) {
    }
}

void Film::develop(float* image, float* variance) const {
    for (size_t i = 0; i < m_pixels.size(); ++i) {
        const Pixel& p = m_pixels[i];
        for (int c = 0; c < 3; ++c) {
            image[3 * i + c] = float(p.mean[c]);
            // weight 1: m2 / ((n - 1) n), the sample variance of the mean
            double var = p.n > 1 && p.w > 0.0 ? std::max(0.0, p.m2[c] / (double(p.n - 1) * p.w)) : 0.0;
            if (variance) variance[3 * i + c] = float(var);
        }
    }
}

bool Film::first_nan(int* x, int* y, uint32_t* sample) const {
    uint64_t key = m_first_nan_key.load();
    if (key == ~uint64_t(0)) return false;
    uint64_t idx = key >> 32;
    *x = int(idx % uint64_t(m_width));
    *y = int(idx / uint64_t(m_width));
    *sample = uint32_t(key & 0xFFFFFFFFu);
    return true;
}

}  // namespace cmlt
