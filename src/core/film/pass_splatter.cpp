// Splatting reconstruction of pixel-sample passes; see pass_splatter.h.
#include "film/pass_splatter.h"

#include "film/film.h"
#include "util/error.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace cmlt {

PassSplatter::PassSplatter(const PixelFilter& filter, Film& film, int row_begin, int row_end)
    : m_filter(filter), m_film(film), m_width(film.width()), m_height(film.height()),
      m_reach(filter.unit_box() ? 0 : int(std::ceil(filter.radius() + 0.5)) - 1),
      m_row0(row_begin), m_row1(row_end < 0 ? film.height() : row_end) {
    CMLT_CHECK(m_reach <= PixelFilter::k_max_footprint && 0 <= m_row0 && m_row0 <= m_row1 &&
               m_row1 <= m_height);
    m_src_y0 = std::max(-m_reach, m_row0 - m_reach);
    m_src_y1 = std::min(m_height + m_reach, m_row1 + m_reach);
    if (m_row0 == m_row1) m_src_y0 = m_src_y1 = m_row0;  // nothing to render
    for (int y = m_src_y0; y < m_src_y1; y += k_tile_size)
        for (int x = -m_reach; x < m_width + m_reach; x += k_tile_size)
            m_tiles.push_back({x, y, std::min(x + k_tile_size, m_width + m_reach), std::min(y + k_tile_size, m_src_y1)});
    const size_t n = size_t(m_width + 2 * m_reach) * size_t(std::max(0, m_src_y1 - m_src_y0));
    m_L.resize(n);
    m_w.resize(n * size_t(2 * (2 * m_reach + 1)));
}

uint32_t PassSplatter::window_key(int x, int y, int width, int height, int reach) {
    if (x >= 0 && y >= 0 && x < width && y < height) return uint32_t(y) * uint32_t(width) + uint32_t(x);
    return uint32_t(width) * uint32_t(height) +
           uint32_t(y + reach) * uint32_t(width + 2 * reach) + uint32_t(x + reach);
}

void PassSplatter::set(int x, int y, const Vec2& p, const Spectrum& L, uint32_t s) {
    const size_t i = index(x, y);
    const int n = 2 * m_reach + 1;
    float* w = &m_w[i * size_t(2 * n)];
    if (!is_finite(L)) {
        // dropped: it weighs nothing anywhere; the film counts it at the nearest pixel
        m_L[i] = Spectrum(0.f);
        std::fill(w, w + 2 * n, 0.f);
        m_film.count_bad_sample(std::min(m_width - 1, std::max(0, x)), std::min(m_height - 1, std::max(0, y)), s);
        return;
    }
    m_L[i] = L;
    if (m_filter.unit_box()) {  // the one-pixel box: the sample's own pixel, weight exactly 1
        w[0] = w[1] = 1.f;
        return;
    }
    for (int d = -m_reach; d <= m_reach; ++d) {
        // toward column x + d (centre x + d + 1/2) and row y + d
        w[d + m_reach] = float(m_filter.evaluate_1d(double(x + d) + 0.5 - double(p.x)));
        w[n + d + m_reach] = float(m_filter.evaluate_1d(double(y + d) + 0.5 - double(p.y)));
    }
}

void PassSplatter::gather(tbb::task_arena& arena, uint32_t s, const double* extra) {
    const int R = m_reach, n = 2 * R + 1;
    arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<int>(m_row0, m_row1), [&](const tbb::blocked_range<int>& r) {
            for (int y = r.begin(); y != r.end(); ++y)
                for (int x = 0; x < m_width; ++x) {
                    // sources k = (x + dx, y + dy) reach j = (x, y) through their weights
                    // toward offset -dx, -dy
                    double a[3] = {0.0, 0.0, 0.0}, b = 0.0;
                    for (int dy = -R; dy <= R; ++dy) {
                        const int ky = y + dy;
                        if (ky < m_src_y0 || ky >= m_src_y1) continue;  // outside the window
                        for (int dx = -R; dx <= R; ++dx) {
                            const size_t i = index(x + dx, ky);
                            const float* w = &m_w[i * size_t(2 * n)];
                            const double f = double(w[R - dx]) * double(w[n + R - dy]);
                            if (f == 0.0) continue;
                            const Spectrum& L = m_L[i];
                            a[0] += f * double(L.x);
                            a[1] += f * double(L.y);
                            a[2] += f * double(L.z);
                            b += f;
                        }
                    }
                    if (b == 0.0) continue;  // (negative lobes cancelling exactly) no sample
                    const size_t j = size_t(y) * size_t(m_width) + size_t(x);
                    double v[3] = {a[0] / b, a[1] / b, a[2] / b};
                    if (extra)
                        for (int c = 0; c < 3; ++c) v[c] += extra[3 * j + c];
                    m_film.add_sample(x, y, s, Spectrum(float(v[0]), float(v[1]), float(v[2])), float(b));
                }
        });
    });
}

}  // namespace cmlt
