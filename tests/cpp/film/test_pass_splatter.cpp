// PassSplatter (film/pass_splatter.h): the splatting reconstruction of pixel-sample
// passes with a wide filter — its keys, its ratio of weighted sums, its independence of
// the order samples arrive in and of row parts, dropped non-finite samples.
#include "film/film.h"
#include "film/pass_splatter.h"
#include "integrators/common/render_settings.h"
#include "sampling/rng.h"
#include "util/error.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <set>
#include <vector>

using namespace cmlt;

namespace {

/// Calls fn(x, y) for every source pixel of the splatter's rows, row-major (the window's
/// columns [-R, W + R)).
template <class Fn>
void for_sources(const PassSplatter& sp, int width, Fn&& fn) {
    for (int y = sp.source_row_begin(); y < sp.source_row_end(); ++y)
        for (int x = -sp.reach(); x < width + sp.reach(); ++x) fn(x, y);
}

/// A deterministic "sample" of source pixel (x, y), pass s: a position in the pixel
/// and a radiance, from the keyed generator (as the integrators' samples are).
void source_sample(const PassSplatter& sp, int x, int y, uint32_t s, Vec2* p, Spectrum* L) {
    PixelSampler smp(5, sp.key(x, y), s);
    const Vec2 u = smp.get2d();
    *p = Vec2(float(x) + u.x, float(y) + u.y);
    const float v = smp.get1d();
    *L = Spectrum(v, 2.f * v * v, 1.f + float(x % 3));
}

/// Render `passes` passes of rows [y0, y1) of a W x H film, the sources set in the
/// order given by `reverse`, with `threads` threads.
std::vector<float> render(const PixelFilter& f, int W, int H, int y0, int y1, int passes, bool reverse,
                          int threads, std::vector<float>* var = nullptr) {
    Film film(W, H);
    PassSplatter sp(f, film, y0, y1);
    tbb::task_arena arena(threads);
    for (int s = 0; s < passes; ++s) {
        std::vector<std::pair<int, int>> order;
        for_sources(sp, W, [&](int x, int y) { order.emplace_back(x, y); });
        if (reverse) std::reverse(order.begin(), order.end());
        for (auto [x, y] : order) {
            Vec2 p;
            Spectrum L;
            source_sample(sp, x, y, uint32_t(s), &p, &L);
            sp.set(x, y, p, L, uint32_t(s));
        }
        sp.gather(arena, uint32_t(s));
    }
    std::vector<float> img(size_t(W) * H * 3), v(img.size());
    film.develop(img.data(), v.data());
    if (var) *var = v;
    return img;
}

}  // namespace

TEST(PassSplatter, ReachAndWindowKeys) {
    Film film(7, 5);
    const PixelFilter box(FilterKind::box, 0.5), gauss(FilterKind::gaussian, 1.5), mitchell(FilterKind::mitchell, 2.0);
    EXPECT_FALSE(PassSplatter(box, film).active());
    EXPECT_EQ(PassSplatter(box, film).reach(), 0);
    EXPECT_EQ(PassSplatter(gauss, film).reach(), 1);   // centres within 1.5 of a point of pixel k: k - 1 .. k + 1
    EXPECT_EQ(PassSplatter(mitchell, film).reach(), 2);
    // keys: y W + x in the image, distinct after it in the ring
    const int W = 7, H = 5, R = 2;
    std::set<uint32_t> keys;
    for (int y = -R; y < H + R; ++y)
        for (int x = -R; x < W + R; ++x) {
            const uint32_t k = PassSplatter::window_key(x, y, W, H, R);
            if (x >= 0 && y >= 0 && x < W && y < H)
                EXPECT_EQ(k, uint32_t(y * W + x));
            else
                EXPECT_GE(k, uint32_t(W * H));
            EXPECT_TRUE(keys.insert(k).second) << x << "," << y;
        }
}

TEST(PassSplatter, ShiftedKeysAreTheKeysOfTheSourcePixelsTheImageCameFrom) {
    // A key shift (the film offset rounded to pixels) gives image pixel (x, y) the key of
    // (x - dx, y - dy) on the image's torus and leaves the ring's keys: a bijection of the
    // window's keys for every shift, negative and beyond the image included, and the
    // identity at (0, 0).
    const int W = 7, H = 5;
    for (int R : {0, 1, 2})
        for (KeyShift s : {KeyShift{0, 0}, KeyShift{1, 0}, KeyShift{0, 3}, KeyShift{6, 4}, KeyShift{-2, -7},
                           KeyShift{W + 1, 2 * H}}) {
            std::set<uint32_t> keys;
            for (int y = -R; y < H + R; ++y)
                for (int x = -R; x < W + R; ++x) {
                    const uint32_t k = PassSplatter::window_key(x, y, W, H, R, s);
                    EXPECT_TRUE(keys.insert(k).second) << R << ": " << x << "," << y;
                    const bool inside = x >= 0 && y >= 0 && x < W && y < H;
                    const int sx = inside ? ((x - s.dx) % W + W) % W : x, sy = inside ? ((y - s.dy) % H + H) % H : y;
                    EXPECT_EQ(k, PassSplatter::window_key(sx, sy, W, H, R)) << R << ": " << x << "," << y;
                }
            EXPECT_EQ(keys.size(), size_t(W + 2 * R) * size_t(H + 2 * R));
        }
    // the film offset (fractions of the image) to whole pixels, wrapped at the image size
    EXPECT_TRUE(KeyShift::of_offset(0.0, 0.0, W, H).identity());
    const KeyShift a = KeyShift::of_offset(0.2, 0.5, W, H);  // 1.4 -> 1, 2.5 -> 3 (half away from 0)
    EXPECT_EQ(a.dx, 1);
    EXPECT_EQ(a.dy, 3);
    const KeyShift b = KeyShift::of_offset(0.99, 0.95, W, H);  // 6.93 -> 7 = W -> 0; 4.75 -> 5 -> 0
    EXPECT_TRUE(b.identity());
    EXPECT_TRUE(KeyShift::of_offset(std::nan(""), -0.5, W, H).identity());  // outside [0, 1): none
}

TEST(PassSplatter, KeyMapsGiveEachImagePixelItsMappedKey) {
    // With a key map (RenderSettings::pixel_keys) image pixel (x, y) takes keys[y W + x],
    // the ring keeps its keys, the film offset is ignored, and the settings' map wins
    // over their offset; every key of the window is still used once.
    const int W = 7, H = 5;
    std::vector<uint32_t> map(size_t(W * H));
    for (size_t i = 0; i < map.size(); ++i) map[i] = uint32_t((i * 12 + 5) % map.size());  // 12 coprime to 35
    RenderSettings st;
    st.width = W;
    st.height = H;
    st.film_offset_x = 0.3;
    st.pixel_keys = std::make_shared<const std::vector<uint32_t>>(map);
    st.validate();
    const KeyShift s = KeyShift::of(st);
    EXPECT_FALSE(s.identity());
    EXPECT_EQ(s.dx, 0);
    for (int R : {0, 2}) {
        std::set<uint32_t> keys;
        for (int y = -R; y < H + R; ++y)
            for (int x = -R; x < W + R; ++x) {
                const uint32_t k = PassSplatter::window_key(x, y, W, H, R, s);
                EXPECT_TRUE(keys.insert(k).second);
                const bool inside = x >= 0 && y >= 0 && x < W && y < H;
                EXPECT_EQ(k, inside ? map[size_t(y * W + x)] : PassSplatter::window_key(x, y, W, H, R));
            }
        EXPECT_EQ(keys.size(), size_t(W + 2 * R) * size_t(H + 2 * R));
    }
    // a map that is not a permutation, or of the wrong size, is refused
    map[3] = map[4];
    st.pixel_keys = std::make_shared<const std::vector<uint32_t>>(map);
    EXPECT_THROW(st.validate(), SettingsError);
    st.pixel_keys = std::make_shared<const std::vector<uint32_t>>(size_t(W * H - 1), 0u);
    EXPECT_THROW(st.validate(), SettingsError);
}

TEST(PassSplatter, OneSourceGivesTheFilterRatio) {
    // Only source (2, 1) is lit: pixel j gets f(c_j - p) L / B_j, B_j the weights of
    // every source within reach (all sources dark but present).
    const PixelFilter f(FilterKind::gaussian, 1.5);
    const int W = 5, H = 4;
    Film film(W, H);
    PassSplatter sp(f, film);
    tbb::task_arena arena(1);
    std::vector<Vec2> pos;
    for_sources(sp, W, [&](int x, int y) {
        const Vec2 p(float(x) + 0.3f + 0.05f * float(x + 1), float(y) + 0.7f - 0.1f * float(y + 1));
        pos.push_back(p);
        sp.set(x, y, p, x == 2 && y == 1 ? Spectrum(1.f, 2.f, 3.f) : Spectrum(0.f), 0);
    });
    sp.gather(arena, 0);
    std::vector<float> img(size_t(W) * H * 3);
    film.develop(img.data(), nullptr);
    const auto at = [&](int x, int y) { return pos[size_t(y + 1) * size_t(W + 2) + size_t(x + 1)]; };
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            double b = 0.0;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    const Vec2 p = at(x + dx, y + dy);
                    b += double(float(f.weight_1d(x + 0.5 - p.x))) * double(float(f.weight_1d(y + 0.5 - p.y)));
                }
            const Vec2 p = at(2, 1);
            const double a = std::abs(x - 2) <= 1 && std::abs(y - 1) <= 1
                                 ? double(float(f.weight_1d(x + 0.5 - p.x))) * double(float(f.weight_1d(y + 0.5 - p.y)))
                                 : 0.0;
            EXPECT_NEAR(img[3 * size_t(y * W + x) + 1], 2.0 * a / b, 1e-6) << x << "," << y;
        }
}

TEST(PassSplatter, ConstantRadianceStaysExact) {
    // A ratio of weighted sums: a uniform image is its radiance in every pixel, with no
    // variance, whatever the positions (the gaussian's and mitchell's negative lobes).
    for (const PixelFilter& f : {PixelFilter(FilterKind::gaussian, 1.5), PixelFilter(FilterKind::mitchell, 2.0),
                                 PixelFilter(FilterKind::blackman_harris, 1.5)}) {
        const int W = 9, H = 6;
        Film film(W, H);
        PassSplatter sp(f, film);
        tbb::task_arena arena(2);
        for (uint32_t s = 0; s < 4; ++s) {
            for_sources(sp, W, [&](int x, int y) {
                PixelSampler smp(3, sp.key(x, y), s);
                const Vec2 u = smp.get2d();
                sp.set(x, y, Vec2(float(x) + u.x, float(y) + u.y), Spectrum(0.25f, 1.f, 4.f), s);
            });
            sp.gather(arena, s);
        }
        std::vector<float> img(size_t(W) * H * 3), var(img.size());
        film.develop(img.data(), var.data());
        for (size_t i = 0; i < size_t(W) * H; ++i) {
            EXPECT_NEAR(img[3 * i], 0.25f, 1e-6) << f.name();
            EXPECT_NEAR(img[3 * i + 2], 4.f, 1e-5) << f.name();
            EXPECT_NEAR(var[3 * i + 1], 0.f, 1e-10) << f.name();
        }
    }
}

TEST(PassSplatter, IndependentOfOrderThreadsAndRowParts) {
    const PixelFilter f(FilterKind::gaussian, 1.5);
    const int W = 37, H = 23;
    std::vector<float> var_a, var_b;
    const std::vector<float> a = render(f, W, H, 0, H, 5, false, 1, &var_a);
    const std::vector<float> b = render(f, W, H, 0, H, 5, true, 2, &var_b);
    EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0);
    EXPECT_EQ(std::memcmp(var_a.data(), var_b.data(), a.size() * sizeof(float)), 0);
    // three row parts, each tracing only the source rows its rows need, give the rows of
    // the whole frame bit for bit
    for (auto [y0, y1] : {std::pair{0, 7}, std::pair{7, 16}, std::pair{16, 23}}) {
        const std::vector<float> part = render(f, W, H, y0, y1, 5, false, 2);
        const size_t off = size_t(y0) * W * 3, n = size_t(y1 - y0) * W * 3;
        EXPECT_EQ(std::memcmp(part.data() + off, a.data() + off, n * sizeof(float)), 0) << y0;
        for (size_t i = 0; i < off; ++i) EXPECT_EQ(part[i], 0.f);  // the other rows stay 0
    }
}

TEST(PassSplatter, NonFiniteSourcesAreDroppedAndCounted) {
    const PixelFilter f(FilterKind::gaussian, 1.5);
    const int W = 6, H = 5;
    Film film(W, H);
    PassSplatter sp(f, film);
    tbb::task_arena arena(1);
    const float bad = std::numeric_limits<float>::quiet_NaN();
    for_sources(sp, W, [&](int x, int y) {
        sp.set(x, y, Vec2(float(x) + 0.5f, float(y) + 0.5f), x == 3 && y == 2 ? Spectrum(bad) : Spectrum(1.f), 9);
    });
    sp.gather(arena, 9);
    std::vector<float> img(size_t(W) * H * 3);
    film.develop(img.data(), nullptr);
    for (float v : img) EXPECT_FLOAT_EQ(v, 1.f);  // the neighbours' samples carry the pixel
    EXPECT_EQ(film.nan_samples(), 1u);
    int x, y;
    uint32_t s;
    ASSERT_TRUE(film.first_nan(&x, &y, &s));
    EXPECT_EQ(x, 3);
    EXPECT_EQ(y, 2);
    EXPECT_EQ(s, 9u);
}

TEST(PassSplatter, SplatCorrelation) {
    EXPECT_EQ(PixelFilter().splat_correlation(), 1.0);
    EXPECT_NEAR(PixelFilter(FilterKind::box, 1.5).splat_correlation(), 9.0, 1e-6);
    // the gaussian of radius 1.5 (sigma 0.5, its value at the radius subtracted):
    // 1 / (∫ f1²)², close to the untruncated gaussian's 4 pi sigma² = 3.14
    const double g = PixelFilter(FilterKind::gaussian, 1.5).splat_correlation();
    EXPECT_GT(g, 2.5);
    EXPECT_LT(g, 3.3);
}
