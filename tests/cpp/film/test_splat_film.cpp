// SplatFilm (film/splat_film.h): exact, order-independent sums in fixed point
// beyond the range of one int64 word. One 64-bit word with 32 fractional bits holds
// ±2^31 per pixel and channel: a bright pixel at a high mutation count (e.g. a pixel
// value of 10^6 under the pixel importance at 4,000 mutations per pixel, or the
// luminance target's L/Y of a saturated colour over 10^8 splats) passes it, and a plain
// int64 sum wrapped around silently (1e9 added 8 times read back as -5.9e8).
#include "film/splat_film.h"
#include "sampling/rng.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <thread>
#include <vector>

using namespace cmlt;

TEST(SplatFilm, SumsBeyondTheInt64RangeStayExact) {
    SplatFilm film(2, 1);
    const Spectrum one{1.f, 1.f, 1.f};
    for (int i = 0; i < 8; ++i) film.add(0, one, 1.0e9);   // 8e9 > 2^31
    for (int i = 0; i < 3; ++i) film.add(1, one, -1.0e9);  // negative side
    for (int k = 0; k < 3; ++k) {
        EXPECT_DOUBLE_EQ(film.sum(0, k), 8.0e9);
        EXPECT_DOUBLE_EQ(film.sum(1, k), -3.0e9);
    }
    EXPECT_EQ(film.clamped(), 0u);
}

TEST(SplatFilm, CarriesCancelExactly) {
    SplatFilm film(1, 1);
    const Spectrum c{0.25f, 1.f, 3.f};
    for (int i = 0; i < 20; ++i) film.add(0, c, 7.0e8);
    for (int i = 0; i < 20; ++i) film.add(0, c, -7.0e8);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(film.sum(0, k), 0.0);
    film.add(0, c, 0.5);  // a small splat after the carries is exact too
    EXPECT_EQ(film.sum(0, 0), 0.125);
    EXPECT_EQ(film.sum(0, 1), 0.5);
    EXPECT_EQ(film.sum(0, 2), 1.5);
}

TEST(SplatFilm, LargeSumsAreIndependentOfOrderAndThreads) {
    // the same 40,000 splats (large and small, both signs) added in order by one thread
    // and shuffled over four threads: bit-identical sums
    std::mt19937_64 gen(7);
    std::uniform_real_distribution<double> mag(0.0, 9.0e8);
    std::vector<std::pair<uint32_t, double>> splats;
    for (int i = 0; i < 40000; ++i) {
        const double w = mag(gen) * ((i % 3 == 0) ? -1.0 : 1.0) * ((i % 7 == 0) ? 1e-6 : 1.0);
        splats.emplace_back(uint32_t(i % 4), w);
    }
    const Spectrum c{1.f, 0.5f, 2.f};
    SplatFilm a(4, 1), b(4, 1);
    for (const auto& s : splats) a.add(s.first, c, s.second);
    std::shuffle(splats.begin(), splats.end(), gen);
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t)
        threads.emplace_back([&, t] {
            for (size_t i = size_t(t); i < splats.size(); i += 4) b.add(splats[i].first, c, splats[i].second);
        });
    for (auto& th : threads) th.join();
    double biggest = 0.0;
    for (size_t p = 0; p < 4; ++p)
        for (int k = 0; k < 3; ++k) {
            EXPECT_EQ(a.sum(p, k), b.sum(p, k)) << "pixel " << p << " channel " << k;
            biggest = std::max(biggest, std::fabs(a.sum(p, k)));
        }
    EXPECT_GT(biggest, 4.0e9);  // the sums really left the one-word range
}

TEST(SplatFilm, FilmsOfDisjointSplatsAddToTheFilmOfAll) {
    // a frame rendered in parts (cmlt.shot.distributed): the parts' exported words added
    // into one film give the sums of the film that received every splat, bit for bit,
    // with carries between the words in both directions
    std::mt19937_64 gen(11);
    std::uniform_real_distribution<double> mag(0.0, 1.0e9);
    const Spectrum c{1.f, 0.25f, 3.f};
    SplatFilm all(3, 2), parts[3] = {SplatFilm(3, 2), SplatFilm(3, 2), SplatFilm(3, 2)};
    for (int i = 0; i < 30000; ++i) {
        const uint32_t pixel = uint32_t(i % 6);
        const double w = mag(gen) * ((i % 5 < 2) ? -1.0 : 1.0) * ((i % 11 == 0) ? 1e-7 : 1.0);
        all.add(pixel, c, w);
        parts[(i * 7) % 3].add(pixel, c, w);
    }
    SplatFilm sum(3, 2);
    for (int p : {2, 0, 1}) {  // any order
        std::vector<uint64_t> lo;
        std::vector<int64_t> hi;
        parts[p].export_words(lo, hi);
        ASSERT_EQ(lo.size(), size_t(3 * 2 * 3));
        sum.add_words(lo.data(), hi.data());
    }
    bool differs_from_a_part = false;
    for (size_t px = 0; px < 6; ++px)
        for (int k = 0; k < 3; ++k) {
            EXPECT_EQ(sum.sum(px, k), all.sum(px, k)) << "pixel " << px << " channel " << k;
            differs_from_a_part = differs_from_a_part || parts[0].sum(px, k) != all.sum(px, k);
        }
    EXPECT_TRUE(differs_from_a_part);
}

TEST(SplatFilm, InlineRoundingIsLlround) {
    // halves (both signs), values next to them, large and tiny magnitudes, and random ones
    std::vector<double> xs = {0.0, -0.0, 0.5, -0.5, 1.5, -1.5, 2.5, -2.5, 0.49999999999999994, -0.49999999999999994,
                              4503599627370495.5, -4503599627370495.5, 4503599627370497.0, 0x1p62, -0x1p62,
                              0x1p62 - 1024.0, 1e-300, -1e-300, 123456789.5, -123456789.5};
    CounterRng rng(4, RngDomain::test, 1);
    for (int i = 0; i < 100000; ++i) {
        const double m = std::ldexp(rng.uniform() * 2.0 - 1.0, int(rng.uniform() * 62.0));
        xs.push_back(m);
        xs.push_back(std::floor(m) + 0.5);
        xs.push_back(std::nextafter(std::floor(m) + 0.5, 0.0));
    }
    for (double x : xs) ASSERT_EQ(SplatFilm::round_half_away(x), std::llround(x)) << x;
}

TEST(SplatFilm, BufferedSplatsGiveTheFilmsWords) {
    // splats of every size and sign over a 40x30 film in two layers, with a gaussian
    // footprint: straight into one film, and through a SplatBuffer per thread (four
    // threads, shuffled, each buffer evicting as pixels collide in its table) into
    // another — the same 128-bit words, so the same sums
    std::mt19937_64 gen(13);
    std::uniform_real_distribution<double> mag(0.0, 2.0e9), unit(0.0, 1.0);
    const int W = 40, H = 30;
    struct Splat {
        Vec2 p;
        uint32_t pixel;
        double w;
        int layer;
    };
    std::vector<Splat> splats;
    for (int i = 0; i < 30000; ++i) {
        // a walk, as a chain's: mostly near the last pixel, now and then anywhere
        const double x = i % 50 == 0 || splats.empty() ? unit(gen) * W : std::clamp(double(splats.back().p.x) + unit(gen) * 3.0 - 1.5, 0.0, W - 1e-3);
        const double y = i % 50 == 0 || splats.empty() ? unit(gen) * H : std::clamp(double(splats.back().p.y) + unit(gen) * 3.0 - 1.5, 0.0, H - 1e-3);
        const double w = mag(gen) * (i % 3 == 0 ? -1.0 : 1.0) * (i % 5 == 0 ? 1e-9 : 1.0);
        splats.push_back({Vec2(float(x), float(y)), uint32_t(int(y) * W + int(x)), w, i % 2});
    }
    const PixelFilter gaussian(FilterKind::gaussian, 1.5);
    const Spectrum c{1.f, 0.375f, 2.5f};
    SplatFilm a(W, H, 2), b(W, H, 2);
    for (const Splat& s : splats) a.add_filtered(gaussian, s.p, s.pixel, c, s.w, s.layer);
    std::shuffle(splats.begin(), splats.end(), gen);
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t)
        threads.emplace_back([&, t] {
            SplatBuffer buffer(b);
            for (size_t i = size_t(t); i < splats.size(); i += 4) {
                const Splat& s = splats[i];
                buffer.add_filtered(gaussian, s.p, s.pixel, c, s.w, s.layer);
                if (i % 4000 == size_t(t)) buffer.flush();  // flushing midway changes nothing
            }
        });  // the rest flushed by the destructor
    for (auto& th : threads) th.join();
    std::vector<uint64_t> alo, blo;
    std::vector<int64_t> ahi, bhi;
    a.export_words(alo, ahi);
    b.export_words(blo, bhi);
    EXPECT_EQ(alo, blo);
    EXPECT_EQ(ahi, bhi);
    for (int l = 0; l < 2; ++l)
        for (size_t p = 0; p < size_t(W * H); ++p)
            for (int k = 0; k < 3; ++k) ASSERT_EQ(a.layer_sum(l, p, k), b.layer_sum(l, p, k)) << l << " " << p;
    EXPECT_EQ(a.clamped(), b.clamped());
}
