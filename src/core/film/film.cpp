#include "film/film.h"

#include "util/error.h"

#include <algorithm>
#include <cmath>
#include <limits>

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
    if (m_block > 1) {
        Blocks& b = m_blocks[idx];
        const uint32_t k = sample_index / m_block;
        if (k != b.current) {
            finish_block(b);
            b.current = k;
        }
        b.n_cur += 1;
        b.w_cur += double(weight);
        for (int c = 0; c < 3; ++c) b.sum_cur[c] += double(weight) * double(L[c]);
    }
    Pixel& p = m_pixels[idx];
    p.n += 1;
    const float l[3] = {L[0], L[1], L[2]};
    track_extremes(p.n, l, weight, p.top, p.top_w, p.bot, p.bot_w);
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

void Film::finish_block(Blocks& b) {
    const double w = b.w_cur;
    const double sum[3] = {b.sum_cur[0], b.sum_cur[1], b.sum_cur[2]};
    b.w_cur = 0.0;
    b.n_cur = 0;
    b.sum_cur[0] = b.sum_cur[1] = b.sum_cur[2] = 0.0;
    if (b.current == ~0u || w == 0.0) return;  // no block yet, or one without a mean
    b.n += 1;
    b.w += w;
    const double m[3] = {sum[0] / w, sum[1] / w, sum[2] / w};
    track_extremes(b.n, m, w, b.top, b.top_w, b.bot, b.bot_w);
    if (b.w == 0.0) return;
    const double share = w / b.w;
    for (int c = 0; c < 3; ++c) {
        const double v = sum[c] / w;
        const double delta = v - b.mean[c];
        b.mean[c] += delta * share;
        b.m2[c] += w * delta * (v - b.mean[c]);
    }
}

template <class T, class V>
void Film::track_extremes(uint32_t n, const V* v, double w, T* top, T& top_w, T* bot, T& bot_w) {
    // the first value is both; from the second on they are two different values (a value
    // above the largest replaces it, else one at or below the smallest replaces that)
    const double sum = double(v[0]) + double(v[1]) + double(v[2]);
    const bool above = n == 1 || sum > double(top[0]) + double(top[1]) + double(top[2]);
    const bool below = n == 1 || (!above && sum <= double(bot[0]) + double(bot[1]) + double(bot[2]));
    if (above) {
        for (int c = 0; c < 3; ++c) top[c] = T(v[c]);
        top_w = T(w);
    }
    if (below) {
        for (int c = 0; c < 3; ++c) bot[c] = T(v[c]);
        bot_w = T(w);
    }
}

void Film::set_variance_block(uint32_t block) {
    CMLT_CHECK(block >= 1);
    m_block = block;
    if (block > 1) m_blocks.assign(m_pixels.size(), Blocks());
    else std::vector<Blocks>().swap(m_blocks);
}

void Film::count_bad_sample(int x, int y, uint32_t sample_index) {
    const size_t idx = size_t(y) * size_t(m_width) + size_t(x);
    m_nan_count.fetch_add(1, std::memory_order_relaxed);
    const uint64_t key = (uint64_t(idx) << 32) | sample_index;
    uint64_t cur = m_first_nan_key.load(std::memory_order_relaxed);
    while (key < cur && !m_first_nan_key.compare_exchange_weak(cur, key)) {
    }
}

namespace {
/// The variance of the mean from a weighted Welford state (weight 1: m2 / ((n - 1) n)).
void variance_of_mean(uint32_t n, double w, const double* m2, float* out) {
    for (int c = 0; c < 3; ++c)
        out[c] = float(n > 1 && w > 0.0 ? std::max(0.0, m2[c] / (double(n - 1) * w)) : 0.0);
}
/// The weighted mean without the largest and the smallest value (`top`, `bot`, with their
/// weights): NaN where fewer than three values or no weight is left (none to take).
void trimmed_mean(uint32_t n, double w, const double* mean, const double* top, double top_w, const double* bot,
                  double bot_w, float* out) {
    const double rest = w - top_w - bot_w;
    for (int c = 0; c < 3; ++c)
        out[c] = n > 2 && rest > 0.0 ? float((w * mean[c] - top_w * top[c] - bot_w * bot[c]) / rest)
                                     : std::numeric_limits<float>::quiet_NaN();
}
}  // namespace

void Film::develop(float* image, float* variance, float* robust) const {
    for (size_t i = 0; i < m_pixels.size(); ++i) {
        const Pixel& p = m_pixels[i];
        for (int c = 0; c < 3; ++c) image[3 * i + c] = float(p.mean[c]);
        if (!variance && !robust) continue;
        if (m_block > 1) {
            // the finished blocks' spread, and the latest block's if it is complete
            Blocks b = m_blocks[i];
            if (b.n_cur == m_block) finish_block(b);
            if (variance) variance_of_mean(b.n, b.w, b.m2, variance + 3 * i);
            if (robust) trimmed_mean(b.n, b.w, b.mean, b.top, b.top_w, b.bot, b.bot_w, robust + 3 * i);
        } else {
            if (variance) variance_of_mean(p.n, p.w, p.m2, variance + 3 * i);
            if (robust) {
                const double top[3] = {p.top[0], p.top[1], p.top[2]}, bot[3] = {p.bot[0], p.bot[1], p.bot[2]};
                trimmed_mean(p.n, p.w, p.mean, top, p.top_w, bot, p.bot_w, robust + 3 * i);
            }
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
