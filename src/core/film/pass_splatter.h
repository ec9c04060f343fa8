#pragma once
/// \file Reconstruction of pixel-sample passes with a wide filter by splatting.
///
/// With a filter wider than the one-pixel box, every camera sample of a pass reaches
/// all the pixels whose filter footprint covers it (Mitsuba's and pbrt-v3's film; not
/// filter importance sampling, which keeps a sample in its pixel and so lets no pixel
/// share its neighbours' samples: tests/bench/results/filters.md measures both).
///
/// A pass s places one sample in every *source* pixel k of the film window — the image
/// and a ring of `reach()` pixels around it, so that every pixel's footprint is covered
/// — at a uniform position p_k in the pixel, with radiance L_k. Pixel j's pass value is
/// the ratio of its weighted sums over the source pixels k within reach,
///
///     A_j = Σ_k f(c_j − p_k) L_k,    B_j = Σ_k f(c_j − p_k),
///
/// added to the Film as one sample of value A_j / B_j and weight B_j: the film's weighted
/// mean is then Σ_s A / Σ_s B over the passes (a consistent ratio estimator of the
/// filtered image ∫ f(c_j − p) L(p) dp, since E[B] = ∫ f = 1 for uniform positions), and
/// its weighted variance still measures each pixel's error (the passes are independent).
/// Each sum runs over the source pixels in a fixed order and the film gets pixel j's
/// passes in index order: the image is bit-identical over thread counts and over row
/// parts of a frame (a part traces the source rows its rows need).
///
/// Source pixels outside the image are keyed after the image's (window_key()), so a
/// pixel's numbers are the same whatever the filter: the image's sources are exactly the
/// unit box's samples. The one-pixel box goes through here too (bdpt, the Metropolis
/// pixel passes): reach 0, each sample to its own pixel with weight exactly 1, the
/// unfiltered film bit for bit; gather() adds a pass's light-tracing splats (`extra`).
#include "film/filter.h"
#include "integrators/common/frame_loop.h"
#include "math/vec.h"

#include <tbb/task_arena.h>

#include <cstdint>
#include <vector>

namespace cmlt {

class Film;

/// Where each pixel's random numbers come from: pixel (x, y) of the image takes the key
/// of pixel (x − dx, y − dy) on the image's torus (source pixels of the ring outside the
/// image keep theirs), so with the frame's
/// film offset (RenderSettings::film_offset_x/y, the image's screen motion rounded to
/// pixels) a pixel sample's numbers travel with the surface it sees: under a pan the
/// noise moves with the image instead of staying on the screen. A bijection of the keys:
/// each pixel still gets its own independent stream and uniform positions, so its
/// estimator is unchanged; (0, 0) is the identity.
/// With a key map (RenderSettings::pixel_keys) image pixel (x, y) takes key
/// keys[y W + x] instead: any permutation of the image's keys, so each pixel can follow
/// its own screen motion (parallax, moving objects); the same argument holds.
struct KeyShift {
    int dx = 0, dy = 0;
    const uint32_t* keys = nullptr;  ///< W·H keys (a permutation), or nullptr
    /// The film offset (fractions of the image, [0, 1)) rounded to whole pixels.
    static KeyShift of_offset(double offset_x, double offset_y, int width, int height);
    /// The frame's: its key map if it has one, else RenderSettings::film_offset_x/y on its
    /// width x height.
    static KeyShift of(const RenderSettings& s) {
        if (s.pixel_keys && !s.pixel_keys->empty()) return KeyShift{0, 0, s.pixel_keys->data()};
        return of_offset(s.film_offset_x, s.film_offset_y, s.width, s.height);
    }
    bool identity() const { return dx == 0 && dy == 0 && !keys; }
};

class PassSplatter {
public:
    /// Output rows [row_begin, row_end) of `film` (row_end < 0: every row).
    PassSplatter(const PixelFilter& filter, Film& film, int row_begin = 0, int row_end = -1);

    /// False for the one-pixel box: each sample goes to its own pixel with weight 1 (the
    /// film then gets value L + extra, weight 1: the unfiltered film bit for bit).
    bool active() const { return m_reach > 0 || !m_filter.unit_box(); }
    /// Source pixels reach pixels up to this many rows/columns away: ceil(r + 1/2) - 1.
    int reach() const { return m_reach; }
    /// The sample key of source pixel (x, y) of the window [-R, W + R) x [-R, H + R):
    /// y W + x inside the image, W H + the window's row-major index outside it; with a
    /// shift, an image pixel takes the key of (x − dx, y − dy) wrapped into the image
    /// (KeyShift).
    static uint32_t window_key(int x, int y, int width, int height, int reach, KeyShift shift = {});
    uint32_t key(int x, int y) const { return window_key(x, y, m_width, m_height, m_reach, m_shift); }
    void set_key_shift(KeyShift shift) { m_shift = shift; }

    /// The source pixels the output rows need, in tiles of at most k_tile_size²
    /// (columns [-R, W + R), rows [row_begin - R, row_end + R) within the window).
    const std::vector<Tile>& source_tiles() const { return m_tiles; }
    int source_row_begin() const { return m_src_y0; }
    int source_row_end() const { return m_src_y1; }
    /// How many source pixels a pass samples (the tiles' pixels).
    double source_pixels() const { return double(m_n); }

    /// The sample of source pixel (x, y) of the current pass: film position `p` (within
    /// the pixel) and radiance `L`. Safe from several threads for different pixels. A
    /// non-finite L is dropped (counted by the film as a bad sample of pass `s`).
    void set(int x, int y, const Vec2& p, const Spectrum& L, uint32_t s);

    /// Add pass `s` to the film: pixel j of the output rows gets A_j / B_j (+ extra_j, a
    /// W x H x 3 image of the pass's light-tracing splats, or null) with weight B_j.
    void gather(tbb::task_arena& arena, uint32_t s, const double* extra = nullptr);

private:
    size_t index(int x, int y) const {
        return size_t(y - m_src_y0) * size_t(m_width + 2 * m_reach) + size_t(x + m_reach);
    }

    const PixelFilter& m_filter;
    Film& m_film;
    int m_width, m_height, m_reach;
    KeyShift m_shift;
    int m_row0, m_row1, m_src_y0, m_src_y1;
    std::vector<Tile> m_tiles;
    // per source pixel i (index()), structure of arrays so that gather() runs along a
    // row of pixels in SIMD lanes: L's channels, and f1 toward column x + d (m_wx[(d + R)
    // N + i]) and row y + d (m_wy[(d + R) N + i]), N the source count (all 0 for a
    // dropped sample)
    size_t m_n = 0;
    std::vector<float> m_L[3];
    std::vector<float> m_wx, m_wy;
};

}  // namespace cmlt
