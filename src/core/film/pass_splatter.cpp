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
    m_n = n;
    for (auto& c : m_L) c.resize(n);
    m_wx.resize(n * size_t(2 * m_reach + 1));
    m_wy.resize(n * size_t(2 * m_reach + 1));
}

KeyShift KeyShift::of_offset(double offset_x, double offset_y, int width, int height) {
    const auto pixels = [](double offset, int n) {
        if (!(offset > 0.0 && offset < 1.0) || n <= 0) return 0;
        return int(std::lround(offset * double(n))) % n;
    };
    return {pixels(offset_x, width), pixels(offset_y, height)};
}

namespace {
/// v − d wrapped into [0, n).
int wrap_shift(int v, int d, int n) {
    int r = (v - d) % n;
    if (r < 0) r += n;
    return r;
}
}  // namespace

uint32_t PassSplatter::window_key(int x, int y, int width, int height, int reach, KeyShift shift) {
    if (x >= 0 && y >= 0 && x < width && y < height) {
        if (shift.keys) return shift.keys[size_t(y) * size_t(width) + size_t(x)];
        if (!shift.identity()) {
            // the image's pixels on the image's torus (the film offset wraps at its size);
            // the ring outside keeps its keys (it only reaches the border pixels' filters)
            x = wrap_shift(x, shift.dx, width);
            y = wrap_shift(y, shift.dy, height);
        }
        return uint32_t(y) * uint32_t(width) + uint32_t(x);
    }
    return uint32_t(width) * uint32_t(height) +
           uint32_t(y + reach) * uint32_t(width + 2 * reach) + uint32_t(x + reach);
}

void PassSplatter::set(int x, int y, const Vec2& p, const Spectrum& L, uint32_t s) {
    const size_t i = index(x, y), N = m_n;
    const int R = m_reach;
    if (!is_finite(L)) {
        // dropped: it weighs nothing anywhere; the film counts it at the nearest pixel
        for (auto& c : m_L) c[i] = 0.f;
        for (int d = -R; d <= R; ++d) m_wx[size_t(d + R) * N + i] = m_wy[size_t(d + R) * N + i] = 0.f;
        m_film.count_bad_sample(std::min(m_width - 1, std::max(0, x)), std::min(m_height - 1, std::max(0, y)), s);
        return;
    }
    m_L[0][i] = L.x;
    m_L[1][i] = L.y;
    m_L[2][i] = L.z;
    if (m_filter.unit_box()) {  // the one-pixel box: the sample's own pixel, weight exactly 1
        m_wx[i] = m_wy[i] = 1.f;
        return;
    }
    for (int d = -R; d <= R; ++d) {
        // toward column x + d (centre x + d + 1/2) and row y + d
        m_wx[size_t(d + R) * N + i] = float(m_filter.weight_1d(double(x + d) + 0.5 - double(p.x)));
        m_wy[size_t(d + R) * N + i] = float(m_filter.weight_1d(double(y + d) + 0.5 - double(p.y)));
    }
}

void PassSplatter::gather(tbb::task_arena& arena, uint32_t s, const double* extra) {
    const int R = m_reach, W = m_width;
    const size_t N = m_n;
    arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<int>(m_row0, m_row1), [&](const tbb::blocked_range<int>& r) {
            // a row's sums, pixel by pixel in lanes: A's channels and B
            std::vector<double> acc(4 * size_t(W));
            double* a0 = acc.data();
            double* a1 = a0 + W;
            double* a2 = a1 + W;
            double* b = a2 + W;
            for (int y = r.begin(); y != r.end(); ++y) {
                std::fill(acc.begin(), acc.end(), 0.0);
                // sources k = (x + dx, y + dy) reach j = (x, y) through their weights
                // toward offset -dx, -dy; every pixel sums them in the same order (dy,
                // then dx), so the image does not depend on the lanes or the threads. A
                // zero weight adds exactly 0 (L is finite), as if it were skipped.
                for (int dy = -R; dy <= R; ++dy) {
                    const int ky = y + dy;
                    if (ky < m_src_y0 || ky >= m_src_y1) continue;  // outside the window
                    const float* wy = &m_wy[size_t(R - dy) * N];
                    for (int dx = -R; dx <= R; ++dx) {
                        const size_t i0 = index(dx, ky);  // source (x + dx, ky) is i0 + x
                        const float* wx = &m_wx[size_t(R - dx) * N + i0];
                        const float* wyr = wy + i0;
                        const float* l0 = &m_L[0][i0];
                        const float* l1 = &m_L[1][i0];
                        const float* l2 = &m_L[2][i0];
                        for (int x = 0; x < W; ++x) {
                            const double f = double(wx[x]) * double(wyr[x]);
                            a0[x] += f * double(l0[x]);
                            a1[x] += f * double(l1[x]);
                            a2[x] += f * double(l2[x]);
                            b[x] += f;
                        }
                    }
                }
                for (int x = 0; x < W; ++x) {
                    if (b[x] == 0.0) continue;  // (negative lobes cancelling exactly) no sample
                    const size_t j = size_t(y) * size_t(W) + size_t(x);
                    double v[3] = {a0[x] / b[x], a1[x] / b[x], a2[x] / b[x]};
                    if (extra)
                        for (int c = 0; c < 3; ++c) v[c] += extra[3 * j + c];
                    m_film.add_sample(x, y, s, Spectrum(float(v[0]), float(v[1]), float(v[2])), float(b[x]));
                }
            }
        });
    });
}

}  // namespace cmlt
