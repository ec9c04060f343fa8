// The pixel samples' low-discrepancy sequence (sampling/sobol.h, PixelSampler with
// PixelSequence::sobol): Sobol dimension 1 by its closed form against its direction
// numbers; the scrambles are bijections that keep every power-of-two prefix (and the
// block at the direct pass's sample base) a (0,m,2)-net; the points are uniform and the
// dimensions uncorrelated across pixels (chi-square at alpha = 1e-3, Bonferroni over
// the two tests); the vectorised lanes (pixel_words_lanes among them) give the scalar
// words; the scramble seeds' hash lets every input bit reach every seed bit (avalanche).
#include "chi2.h"

#include "integrators/bdpt/path_sampler.h"
#include "sampling/rng.h"
#include "sampling/rng_domains.h"
#include "sampling/sobol.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <set>
#include <vector>

using namespace cmlt;
using cmlt::test::Chi2Result;
using cmlt::test::chi2_test;

namespace {

constexpr double k_alpha = 1e-3 / 2.0;

uint32_t sobol1_by_direction_numbers(uint32_t j) {
    uint32_t out = 0, v = 0x80000000u;
    for (; j != 0; j >>= 1, v ^= v >> 1)
        if (j & 1u) out ^= v;
    return out;
}

/// Is every 2^a × 2^(m−a) cell of the unit square hit exactly once by the 2^m points?
bool is_net(const std::vector<std::pair<uint32_t, uint32_t>>& pts, int m) {
    if (pts.size() != (size_t(1) << m)) return false;
    for (int a = 0; a <= m; ++a) {
        std::set<uint64_t> cells;
        for (const auto& p : pts) {
            const uint64_t cx = a == 0 ? 0 : p.first >> (32 - a);
            const uint64_t cy = a == m ? 0 : p.second >> (32 - (m - a));
            if (!cells.insert((cx << 32) | cy).second) return false;
        }
    }
    return true;
}

std::vector<std::pair<uint32_t, uint32_t>> pixel_points(uint32_t pixel, uint32_t dim, uint32_t first, uint32_t n,
                                                        PixelSequence seq = PixelSequence::sobol) {
    std::vector<std::pair<uint32_t, uint32_t>> out;
    const Philox4x32Key key = seed_key(7);
    for (uint32_t i = 0; i < n; ++i) {
        uint32_t w[2];
        pixel_words(key, seq, pixel, first + i, dim, RngStream::camera_path, w);
        out.push_back({w[0], w[1]});
    }
    return out;
}

}  // namespace

TEST(Sobol, DimensionOneIsTheDirectionNumbersXor) {
    CounterRng rng(3, RngDomain::test, 0);
    for (uint32_t j = 0; j < 4096; ++j) EXPECT_EQ(sobol::sobol1(j), sobol1_by_direction_numbers(j)) << j;
    for (int k = 0; k < 10000; ++k) {
        const uint32_t j = uint32_t(rng.uniform() * 4294967296.0);
        ASSERT_EQ(sobol::sobol1(j), sobol1_by_direction_numbers(j)) << j;
    }
    EXPECT_EQ(sobol::sobol1(0xFFFFFFFFu), sobol1_by_direction_numbers(0xFFFFFFFFu));
}

TEST(Sobol, ScrambleIsABijectionThatKeepsTopBitBlocks) {
    // 16-bit sub-space: the top 16 bits of the scramble of i < 2^16 are one constant,
    // and the low 16 bits run through every value once.
    for (uint32_t seed : {0u, 1u, 0xDEADBEEFu}) {
        std::set<uint32_t> low;
        const uint32_t top = sobol::nested_uniform_scramble(0, seed) >> 16;
        for (uint32_t i = 0; i < 65536; ++i) {
            const uint32_t s = sobol::nested_uniform_scramble(i, seed);
            ASSERT_EQ(s >> 16, top);
            low.insert(s & 0xFFFFu);
        }
        EXPECT_EQ(low.size(), 65536u);
    }
}

TEST(Sobol, EveryPowerOfTwoPrefixOfAPixelIsANet) {
    for (uint32_t pixel : {0u, 17u, 123456u})
        for (uint32_t dim : {0u, 1u, 9u, k_lens_dimension})
            for (int m = 0; m <= 10; ++m) {
                EXPECT_TRUE(is_net(pixel_points(pixel, dim, 0, 1u << m), m)) << pixel << " " << dim << " " << m;
                // the direct pass's samples start at an aligned base
                EXPECT_TRUE(is_net(pixel_points(pixel, dim, k_direct_sample_base, 1u << m), m))
                    << "direct pass " << pixel << " " << dim << " " << m;
            }
    // and a sample count that is not a power of two is not a net of its own, but its
    // aligned blocks are: samples [512, 768) of 768
    EXPECT_TRUE(is_net(pixel_points(5, 2, 512, 256), 8));
}

TEST(Sobol, PointsAreUniformAndDimensionsIndependentAcrossPixels) {
    // one sample (index 5) of 2^16 pixels: (first word of dimension 0, first word of
    // dimension 1) on a 16 x 16 grid, and dimension 3's own two words on another
    constexpr int k_cells = 16, k_pixels = 1 << 16;
    std::vector<double> cross(k_cells * k_cells, 0.0), own(k_cells * k_cells, 0.0);
    const Philox4x32Key key = seed_key(11);
    for (uint32_t p = 0; p < uint32_t(k_pixels); ++p) {
        uint32_t a[2], b[2], c[2];
        pixel_words(key, PixelSequence::sobol, p, 5, 0, RngStream::camera_path, a);
        pixel_words(key, PixelSequence::sobol, p, 5, 1, RngStream::camera_path, b);
        pixel_words(key, PixelSequence::sobol, p, 5, 3, RngStream::camera_path, c);
        cross[(a[0] >> 28) * k_cells + (b[0] >> 28)] += 1.0;
        own[(c[0] >> 28) * k_cells + (c[1] >> 28)] += 1.0;
    }
    const std::vector<double> expected(k_cells * k_cells, double(k_pixels) / (k_cells * k_cells));
    const Chi2Result r1 = chi2_test(cross, expected), r2 = chi2_test(own, expected);
    EXPECT_TRUE(r1.passed(k_alpha)) << "p = " << r1.p_value;
    EXPECT_TRUE(r2.passed(k_alpha)) << "p = " << r2.p_value;
}

TEST(Sobol, LanesGiveTheScalarWords) {
    CounterRng rng(5, RngDomain::test, 1);
    for (uint32_t index : {0u, 37u, 1000u, k_direct_sample_base + 3u}) {
        std::vector<uint32_t> w0, w1, s0, s1;
        for (int i = 0; i < 1000; ++i) {
            s0.push_back(uint32_t(rng.uniform() * 4294967296.0));
            s1.push_back(uint32_t(rng.uniform() * 4294967296.0));
        }
        w0 = s0;
        w1 = s1;
        sobol::scrambled_points_lanes(w0.size(), index, w0.data(), w1.data());
        for (size_t i = 0; i < w0.size(); ++i) {
            uint32_t w[2];
            sobol::scrambled_point(index, s0[i], s1[i], w);
            ASSERT_EQ(w0[i], w[0]) << index << " " << i;
            ASSERT_EQ(w1[i], w[1]) << index << " " << i;
        }
    }
}

TEST(Sobol, ScrambleSeedsAvalanche) {
    // Flipping one bit of any input word (key, pixel, sequence, dimension, stream) flips
    // each bit of both seed words with probability 1/2: over 2048 random inputs every
    // (input bit, seed bit) pair's rate within 0.5 +- 0.08 (7 standard deviations of a
    // fair rate). A word left out of the hash, or mixed in too weakly, fails by far.
    CounterRng rng(3, RngDomain::test, 2);
    constexpr int k_trials = 2048;
    std::vector<std::array<uint32_t, 6>> inputs(k_trials);
    for (auto& in : inputs)
        for (uint32_t& w : in) w = uint32_t(rng.uniform() * 4294967296.0);
    const auto seeds = [](const std::array<uint32_t, 6>& in, uint32_t* a, uint32_t* b) {
        sobol::scramble_seeds(in[0], in[1], in[2], in[3], in[4], in[5], a, b);
    };
    double worst = 0.0;
    for (int word = 0; word < 6; ++word)
        for (int bit = 0; bit < 32; ++bit) {
            std::array<int, 64> flips{};
            for (const auto& in : inputs) {
                uint32_t a, b, a2, b2;
                seeds(in, &a, &b);
                auto flipped = in;
                flipped[size_t(word)] ^= 1u << bit;
                seeds(flipped, &a2, &b2);
                for (int k = 0; k < 32; ++k) {
                    flips[size_t(k)] += int(((a ^ a2) >> k) & 1u);
                    flips[size_t(32 + k)] += int(((b ^ b2) >> k) & 1u);
                }
            }
            for (int f : flips) worst = std::max(worst, std::fabs(double(f) / k_trials - 0.5));
        }
    EXPECT_LT(worst, 0.08);
}

TEST(Sobol, ScrambleSeedsOfDifferentKeysMeetOnlyByChance) {
    // Renders with different seeds must not share their numbers on some map of the
    // pixels: over 256 x 256 pixels and 8 dimensions, how many of key k's seed words
    // key k' also has. Chance alone gives about 2^19 · 2^19 / 2^32 = 64 per pair; a key
    // folded into the pixel word (seed s's pixel p = seed s′'s p ^ s ^ s′) gives all
    // 2^19.
    constexpr uint32_t k_pixels = 1u << 16, k_dims = 8;
    std::vector<std::vector<uint32_t>> words(4);
    for (uint32_t k = 0; k < words.size(); ++k) {
        const Philox4x32Key key = seed_key(uint64_t(k) + 1);
        for (uint32_t p = 0; p < k_pixels; ++p)
            for (uint32_t d = 0; d < k_dims; ++d) {
                uint32_t a, b;
                sobol::scramble_seeds(key[0], key[1], p, k_sequence_seed_sample, d, 0u, &a, &b);
                words[k].push_back(a);
            }
        std::sort(words[k].begin(), words[k].end());
    }
    for (size_t k = 0; k < words.size(); ++k)
        for (size_t j = k + 1; j < words.size(); ++j) {
            std::vector<uint32_t> common;
            std::set_intersection(words[k].begin(), words[k].end(), words[j].begin(), words[j].end(),
                                  std::back_inserter(common));
            EXPECT_LT(common.size(), 200u) << "keys " << k + 1 << " and " << j + 1;
        }
}

TEST(Sobol, SeedLanesGiveTheScalarSeeds) {
    // prefixes of pixels of one sequence, then dimensions of lanes of several prefixes
    CounterRng rng(9, RngDomain::test, 3);
    const uint32_t sequence = k_sequence_seed_sample - 5u;
    std::vector<uint32_t> pixel(1000), prefix(1000), dim(1000), w0(1000), w1(1000);
    for (size_t i = 0; i < pixel.size(); ++i) pixel[i] = uint32_t(rng.uniform() * 4294967296.0);
    sobol::seed_prefix_lanes(pixel.size(), pixel.data(), sequence, 17u, prefix.data());
    std::vector<uint32_t> lane_prefix(1000);
    for (size_t i = 0; i < dim.size(); ++i) {
        lane_prefix[i] = prefix[i / 5];  // five dimensions of each of the first 200 pixels
        dim[i] = uint32_t(i % 5) + uint32_t(i / 5) * 3u;
    }
    const uint32_t key_hash = sobol::seed_key_hash(0x1234u, 0xabcdu);
    sobol::dimension_seeds_lanes(dim.size(), lane_prefix.data(), dim.data(), key_hash, w0.data(), w1.data());
    for (size_t i = 0; i < dim.size(); ++i) {
        ASSERT_EQ(prefix[i], sobol::seed_prefix(pixel[i], sequence, 17u)) << i;
        uint32_t a, b;
        sobol::scramble_seeds(0x1234u, 0xabcdu, pixel[i / 5], sequence, dim[i], 17u, &a, &b);
        ASSERT_EQ(w0[i], a) << i;
        ASSERT_EQ(w1[i], b) << i;
    }
}

TEST(Sobol, PixelSamplerReadsTheSequence) {
    // the sampler's numbers are the words' floats, independent ones differ
    PixelSampler sobol(7, 42, 3, RngStream::camera_path, PixelSequence::sobol);
    PixelSampler independent(7, 42, 3);
    uint32_t w[2];
    pixel_words(seed_key(7), PixelSequence::sobol, 42, 3, 0, RngStream::camera_path, w);
    const Vec2 u = sobol.get2d(), v = independent.get2d();
    EXPECT_EQ(u.x, uint_to_unit_float(w[0]));
    EXPECT_EQ(u.y, uint_to_unit_float(w[1]));
    EXPECT_NE(u.x, v.x);
}

TEST(Sobol, SamplersKeepingTheSharedSeedPartsGiveTheWordsOfEachDimension) {
    // PixelSampler and PixelStreamSampler keep the seeds' per-sample parts (SequenceSeeds)
    // from the first draw on, and PixelStreamSampler computes each stream's dimensions in
    // blocks ahead (30 draws per stream here: across several blocks); every later
    // dimension, in any stream order, is still pixel_words's (a one-dimensional draw,
    // get1d or next1d, its first word)
    for (PixelSequence seq : {PixelSequence::sobol, PixelSequence::sobol_blocks, PixelSequence::independent}) {
        PixelSampler ps(7, 42, 19, RngStream::camera_path, seq);
        for (uint32_t d = 0; d < 12; ++d) {
            uint32_t w[2];
            pixel_words(seed_key(7), seq, 42, 19, d, RngStream::camera_path, w);
            if (d % 3 == 1) {
                ASSERT_EQ(ps.get1d(), uint_to_unit_float(w[0])) << d;
                continue;
            }
            const Vec2 u = ps.get2d();
            ASSERT_EQ(u.x, uint_to_unit_float(w[0])) << d;
            ASSERT_EQ(u.y, uint_to_unit_float(w[1])) << d;
        }
        PixelStreamSampler bs(7, 42, 19, seq);
        uint32_t dim[3] = {0, 0, 0};
        for (int k = 0; k < 90; ++k) {
            const int stream = (k * 5 + k / 3) % 3;
            bs.start_stream(stream);
            uint32_t w[2];
            pixel_words(seed_key(7), seq, 42, 19, dim[stream]++, RngStream(uint32_t(RngStream::bdpt_camera) + uint32_t(stream)), w);
            if (k % 2) {
                ASSERT_EQ(bs.next1d(), uint_to_unit_float(w[0])) << k;
                continue;
            }
            const Vec2 u = bs.next2d();
            ASSERT_EQ(u.x, uint_to_unit_float(w[0])) << k;
            ASSERT_EQ(u.y, uint_to_unit_float(w[1])) << k;
        }
    }
}

TEST(Sobol, PixelWordsLanesGiveTheWordsOfEachDimension) {
    // pixel_words_lanes: n dimensions from d0 at once, for every sequence and n, equal to
    // pixel_words of each (with fresh SequenceSeeds, then with those the first call kept)
    for (PixelSequence seq : {PixelSequence::sobol, PixelSequence::sobol_blocks, PixelSequence::independent}) {
        for (uint32_t n = 1; n <= k_pixel_words_lanes; ++n) {
            const uint32_t d0 = 3 * n + 1, pixel = 1000 + 17 * n, sample = 5 * n;
            const RngStream stream = RngStream(uint32_t(RngStream::bdpt_camera) + n % 3);
            uint32_t w0[k_pixel_words_lanes], w1[k_pixel_words_lanes];
            SequenceSeeds fresh;
            pixel_words_lanes(seed_key(9), seq, pixel, sample, d0, n, stream, w0, w1, &fresh);
            for (uint32_t i = 0; i < n; ++i) {
                uint32_t w[2];
                pixel_words(seed_key(9), seq, pixel, sample, d0 + i, stream, w);
                ASSERT_EQ(w0[i], w[0]) << n << " " << i;
                ASSERT_EQ(w1[i], w[1]) << n << " " << i;
            }
            // a second block of the same sample and stream with the parts kept
            pixel_words_lanes(seed_key(9), seq, pixel, sample, d0 + n, n, stream, w0, w1, &fresh);
            for (uint32_t i = 0; i < n; ++i) {
                uint32_t w[2];
                pixel_words(seed_key(9), seq, pixel, sample, d0 + n + i, stream, w);
                ASSERT_EQ(w0[i], w[0]) << n << " " << i;
                ASSERT_EQ(w1[i], w[1]) << n << " " << i;
            }
        }
    }
}

TEST(Sobol, BlocksAreNetsOfTheirOwn) {
    // sobol-blocks: every block of k_sobol_block samples (from 0 and from the direct
    // pass's base) is a net, scrambled independently: blocks differ from each other;
    // block 0 has the one sequence's seeds (its first points), the next ones do not
    const uint32_t B = k_sobol_block;
    int m = 0;
    while ((1u << m) < B) ++m;
    ASSERT_EQ(1u << m, B);
    for (uint32_t pixel : {0u, 9u})
        for (uint32_t dim : {0u, 4u})
            for (uint32_t base : {0u, k_direct_sample_base})
                for (uint32_t k = 0; k < 4; ++k) {
                    const auto pts = pixel_points(pixel, dim, base + k * B, B, PixelSequence::sobol_blocks);
                    EXPECT_TRUE(is_net(pts, m)) << pixel << " " << dim << " " << k;
                    EXPECT_NE(pts, pixel_points(pixel, dim, base + (k + 1) * B, B, PixelSequence::sobol_blocks));
                }
    EXPECT_EQ(pixel_points(3, 1, 0, B, PixelSequence::sobol_blocks), pixel_points(3, 1, 0, B));
    EXPECT_NE(pixel_points(3, 1, B, B, PixelSequence::sobol_blocks), pixel_points(3, 1, B, B));
    // and two blocks together are not a net (independent scrambles do not stratify
    // against each other), except by chance: over many pixels most are not
    int nets = 0;
    for (uint32_t pixel = 0; pixel < 64; ++pixel)
        nets += is_net(pixel_points(pixel, 2, 0, 2 * B, PixelSequence::sobol_blocks), m + 1) ? 1 : 0;
    EXPECT_LT(nets, 32);
}
