// The RNG module's registry (sampling/rng_domains.h) and shared conversions
// (sampling/rng.h): the counter spaces stay disjoint and the conversions keep every
// primary sample in [0, 1); CounterRng's normals (Box–Muller pairs) are independent
// standard normals (chi-square at alpha = 1e-3).
#include "chi2.h"
#include "sampling/rng.h"
#include "sampling/rng_domains.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <vector>

using namespace cmlt;

TEST(RngDomains, MetropolisDomainsAreDistinctAndFitTheirByte) {
    const RngDomain all[] = {RngDomain::bootstrap,      RngDomain::chain,      RngDomain::resample,
                             RngDomain::carry_evaluate, RngDomain::carry_keep, RngDomain::carry_refresh,
                             RngDomain::test};
    std::set<uint32_t> seen;
    for (RngDomain d : all) {
        EXPECT_LT(uint32_t(d), 256u);
        EXPECT_TRUE(seen.insert(uint32_t(d)).second) << uint32_t(d);
    }
}

TEST(RngDomains, PixelAndMetropolisCountersNeverMeet) {
    // Pixel counters end in a stream id below 2^16; Metropolis counters in a word whose
    // top byte is 0x10 + tag.
    const RngStream streams[] = {RngStream::camera_path, RngStream::bdpt_camera, RngStream::bdpt_light,
                                 RngStream::bdpt_connection, RngStream::test};
    for (RngStream s : streams) EXPECT_LT(pixel_counter(1, 2, 3, s)[3], 1u << 16);
    const RngTag tags[] = {RngTag::point, RngTag::sequence, RngTag::small_step, RngTag::keyed};
    std::set<uint32_t> words;
    for (RngTag t : tags) {
        const uint32_t w = metropolis_counter(t, RngDomain::chain, 4, 0xFFFF00000005ull, 6)[3];
        EXPECT_GE(w, 1u << 28);
        EXPECT_EQ(w >> 24, 0x10u + uint32_t(t));
        EXPECT_EQ((w >> 16) & 0xFFu, uint32_t(RngDomain::chain));
        EXPECT_EQ(w & 0xFFFFu, 0xFFFFu);  // the draw's high 16 bits
        EXPECT_TRUE(words.insert(w).second);
    }
    // the Metropolis layout is part of the state files' meaning: it must not move
    EXPECT_EQ(metropolis_counter(RngTag::point, RngDomain::bootstrap, 5, 7, 3),
              (Philox4x32Counter{5u, 7u, 3u, 0x10010000u}));
}

TEST(RngDomains, PassSampleBasesAreDisjointFromEachOtherAndFromPixelSamples) {
    // pt / bdpt sample indices count up from 0; each pass owns 2^29 indices
    EXPECT_GE(k_direct_sample_base, 1u << 29);
    EXPECT_GE(k_pilot_sample_base - k_direct_sample_base, 1u << 29);
    EXPECT_GT(k_lens_dimension, k_shutter_time_dimension);
    EXPECT_GE(k_shutter_time_dimension, 1u << 31);
}

TEST(Rng, UnitFloatAndWrapStayBelowOne) {
    EXPECT_EQ(unit_float(0.5), 0.5f);
    EXPECT_EQ(unit_float(0.0), 0.f);
    const double just_below = std::nextafter(1.0, 0.0);  // rounds to 1.0f
    EXPECT_EQ(float(just_below), 1.f);
    EXPECT_LT(unit_float(just_below), 1.f);
    EXPECT_EQ(unit_float(just_below), std::nextafter(1.f, 0.f));
    EXPECT_EQ(wrap01(-1e-17), 0.0);
    EXPECT_DOUBLE_EQ(wrap01(-0.25), 0.75);
    EXPECT_EQ(wrap01(std::numeric_limits<double>::quiet_NaN()), 0.0);
    EXPECT_EQ(wrap01(std::numeric_limits<double>::infinity()), 0.0);
    EXPECT_LT(bits_to_unit(~0u, ~0u), 1.0);
    EXPECT_LT(uint_to_unit_float(~0u), 1.f);
}

TEST(Rng, CounterRngIsAPureFunctionOfItsKey) {
    CounterRng a(3, RngDomain::chain, 1), b(3, RngDomain::chain, 1), c(3, RngDomain::chain, 2),
        d(3, RngDomain::bootstrap, 1), e(4, RngDomain::chain, 1);
    const double va = a.uniform();
    EXPECT_EQ(va, b.uniform());
    EXPECT_NE(va, c.uniform());
    EXPECT_NE(va, d.uniform());
    EXPECT_NE(va, e.uniform());
    for (int i = 0; i < 1000; ++i) {
        const double u = a.uniform();
        ASSERT_GE(u, 0.0);
        ASSERT_LT(u, 1.0);
        ASSERT_TRUE(std::isfinite(a.normal()));
    }
}

TEST(Philox, LanesGiveTheBitsOfOneCallAtATime) {
    // philox4x32_lanes (the vectorised loop) against philox4x32 on counters spread over
    // every word, with the key of a 64-bit seed.
    const size_t n = 1037;  // not a multiple of any vector width
    std::vector<uint32_t> c0(n), c1(n), c2(n), w0(n), w1(n);
    for (size_t i = 0; i < n; ++i) {
        c0[i] = uint32_t(i * 2654435761u);
        c1[i] = uint32_t(i ^ 0xA5A5A5A5u);
        c2[i] = uint32_t(0xFFFFFFFFu - i);
    }
    const Philox4x32Key key = seed_key(0x0123456789ABCDEFull);
    philox4x32_lanes(n, c0.data(), c1.data(), c2.data(), 77u, key, w0.data(), w1.data());
    for (size_t i = 0; i < n; ++i) {
        const Philox4x32Counter r = philox4x32({c0[i], c1[i], c2[i], 77u}, key);
        ASSERT_EQ(w0[i], r[0]) << i;
        ASSERT_EQ(w1[i], r[1]) << i;
    }
}

TEST(Rng, CounterRngNormalsArePairsOfIndependentStandardNormals) {
    // normal() returns a Box-Muller pair's cosine branch, then its sine branch: the pair
    // (z1, z2) must be two independent N(0, 1). Phi maps each to a uniform; a 10 x 10
    // chi-square of (Phi(z1), Phi(z2)) checks both margins and their independence (a
    // sine branch equal or tied to the cosine one, or a branch reused, fails).
    CounterRng rng(11, RngDomain::test, 7);
    const int cells = 10, n = 200000;
    std::vector<double> obs(size_t(cells * cells), 0.0), exp(size_t(cells * cells), double(n) / (cells * cells));
    auto phi = [](double z) { return 0.5 * std::erfc(-z / std::sqrt(2.0)); };
    for (int k = 0; k < n; ++k) {
        const double z1 = rng.normal(), z2 = rng.normal();
        ASSERT_TRUE(std::isfinite(z1) && std::isfinite(z2));
        const int a = std::min(cells - 1, int(phi(z1) * cells)), b = std::min(cells - 1, int(phi(z2) * cells));
        obs[size_t(a * cells + b)] += 1.0;
    }
    const test::Chi2Result r = test::chi2_test(obs, exp);
    EXPECT_TRUE(r.passed(1e-3)) << r.message;
    // the first normal of a generator is box_muller of its first two uniforms
    CounterRng g(11, RngDomain::test, 8), h(11, RngDomain::test, 8);
    const double u1 = h.uniform();
    EXPECT_EQ(g.normal(), box_muller(u1, h.uniform()));
}
