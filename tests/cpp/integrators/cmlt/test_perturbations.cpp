// Coherent MLT's perturbations (integrators/cmlt/perturbations.h), driven directly: what
// each one moves and leaves, that its offsets are the symmetric wrapped Gaussian of its
// σ (so the kernels' symmetric-proposal rules apply), the pixel move's uniform redraw,
// and the choice of a perturbation per inner step.
//
// False alarms: each statistical check holds its stated level; per test at most 1e-3.
#include "chi2.h"

#include "integrators/cmlt/perturbations.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

using namespace cmlt;
using namespace cmlt::coherent;
using namespace cmlt::test;

namespace {

constexpr uint64_t k_seed = 99;
constexpr int k_width = 64, k_height = 32;
constexpr double k_sigma = 0.01;

/// A state whose path read 4 camera, 6 light and 2 connection slots, with one override.
State read_state() {
    State x;
    x.key = StateKey{RngDomain::chain, 5, 3};
    x.set(MltSampler::index(MltSampler::light, 1), 0.5);
    x.extent = {4, 6, 2};
    x.evaluated = true;
    return x;
}

/// (b − a) wrapped to [−1/2, 1/2).
double wrapped_difference(double a, double b) {
    double d = b - a;
    return d - std::floor(d + 0.5);
}

PerturbationProposal make(Perturbation kind) {
    CounterRng rng(k_seed, RngDomain::test, 0);  // draws a small step's refresh
    return PerturbationProposal::make(kind, k_seed, k_sigma * double(std::max(k_width, k_height)), k_sigma, k_width,
                                      k_height, rng);
}

/// Over n proposals from x: the wrapped offsets of coordinate i, and whether any other
/// coordinate in [0, 40) changed.
std::vector<double> offsets(const PerturbationProposal& p, const State& x, size_t i, int n, bool* others_moved,
                            const std::vector<size_t>& moving) {
    CounterRng rng(7, RngDomain::test, uint32_t(i));
    std::vector<double> d;
    State y;
    for (int k = 0; k < n; ++k) {
        p.sample(x, y, rng);
        EXPECT_FALSE(y.evaluated);
        d.push_back(wrapped_difference(x.value(k_seed, i), y.value(k_seed, i)));
        for (size_t j = 0; j < 40; ++j) {
            bool moves = false;
            for (size_t m : moving) moves = moves || m == j;
            if (!moves && y.value(k_seed, j) != x.value(k_seed, j)) *others_moved = true;
        }
    }
    return d;
}

/// The offsets are N(0, σ²) (mean and variance within 4.5 standard errors) and symmetric:
/// a chi-square of the histogram of d against that of −d (the kernel K(x, y) = K(y, x)).
void expect_symmetric_gaussian(const std::vector<double>& d, double sigma) {
    const double n = double(d.size());
    double m = 0, v = 0;
    for (double x : d) m += x;
    m /= n;
    for (double x : d) v += (x - m) * (x - m);
    v /= n - 1;
    EXPECT_NEAR(m, 0.0, 4.5 * sigma / std::sqrt(n));
    EXPECT_NEAR(v, sigma * sigma, 4.5 * sigma * sigma * std::sqrt(2.0 / n));
    constexpr int k_bins = 16;  // over ±3σ, mirrored pairs
    std::vector<double> pos(k_bins, 0.0), neg(k_bins, 0.0);
    for (double x : d) {
        const int b = int(std::fabs(x) / (3.0 * sigma) * k_bins);
        if (b >= k_bins) continue;
        (x >= 0 ? pos : neg)[size_t(b)] += 1.0;
    }
    // given the count of a mirrored pair, each side is Binomial(count, 1/2)
    std::vector<double> obs, exp;
    for (int b = 0; b < k_bins; ++b) {
        obs.push_back(pos[size_t(b)]);
        exp.push_back(0.5 * (pos[size_t(b)] + neg[size_t(b)]));
    }
    const Chi2Result c = chi2_test(obs, exp);
    EXPECT_TRUE(c.passed(1e-3)) << c.message;
}

}  // namespace

TEST(Perturbations, LensMovesTheFilmPositionByItsPixelSigmaAndNothingElse) {
    const State x = read_state();
    const PerturbationProposal p = make(Perturbation::lens);
    const size_t f0 = film_index(0), f1 = film_index(1);
    EXPECT_EQ(f0, MltSampler::index(MltSampler::camera, 0));
    EXPECT_EQ(f1, MltSampler::index(MltSampler::camera, 1));
    bool others = false;
    const double sigma_pixels = k_sigma * k_width;
    expect_symmetric_gaussian(offsets(p, x, f0, 20000, &others, {f0, f1}), sigma_pixels / k_width);
    expect_symmetric_gaussian(offsets(p, x, f1, 20000, &others, {f0, f1}), sigma_pixels / k_height);
    EXPECT_FALSE(others);
}

TEST(Perturbations, CausticMovesTheEmissionDirectionAndNothingElse) {
    const State x = read_state();
    const PerturbationProposal p = make(Perturbation::caustic);
    const size_t c0 = caustic_index(0), c1 = caustic_index(1);
    // light stream: light choice (dimension 0), emission position (1), direction (2)
    EXPECT_EQ(c0, MltSampler::index(MltSampler::light, 2 * MltSampler::k_slots_per_dimension));
    EXPECT_EQ(c1, c0 + MltSampler::k_stream_count);
    bool others = false;
    expect_symmetric_gaussian(offsets(p, x, c0, 20000, &others, {c0, c1}), k_sigma);
    expect_symmetric_gaussian(offsets(p, x, c1, 20000, &others, {c0, c1}), k_sigma);
    EXPECT_FALSE(others);
}

TEST(Perturbations, PixelMoveRedrawsTheFilmPositionUniformly) {
    const State x = read_state();
    const PerturbationProposal p = make(Perturbation::pixel_move);
    CounterRng rng(3, RngDomain::test, 1);
    constexpr int k_bins = 8, k_n = 16000;
    std::vector<double> counts(k_bins * k_bins, 0.0), expected(k_bins * k_bins, double(k_n) / (k_bins * k_bins));
    State y;
    for (int k = 0; k < k_n; ++k) {
        p.sample(x, y, rng);
        const double a = y.value(k_seed, film_index(0)), b = y.value(k_seed, film_index(1));
        ASSERT_TRUE(a >= 0.0 && a < 1.0 && b >= 0.0 && b < 1.0);
        counts[size_t(int(a * k_bins) * k_bins + int(b * k_bins))] += 1.0;
        for (size_t j = 0; j < 40; ++j)
            if (j != film_index(0) && j != film_index(1)) { ASSERT_EQ(y.value(k_seed, j), x.value(k_seed, j)) << j; }
    }
    const Chi2Result c = chi2_test(counts, expected);
    EXPECT_TRUE(c.passed(1e-3)) << c.message;
}

TEST(Perturbations, SmallStepMovesEveryCoordinateButTheTechnique) {
    const State x = read_state();
    const PerturbationProposal p = make(Perturbation::small_step);
    CounterRng rng(4, RngDomain::test, 2);
    const size_t t0 = MltSampler::index(MltSampler::connection, 0), t1 = MltSampler::index(MltSampler::connection, 1);
    State y;
    std::vector<double> d;
    for (int k = 0; k < 4000; ++k) {
        p.sample(x, y, rng);
        EXPECT_EQ(y.extent, x.extent);
        for (uint32_t s = 0; s < MltSampler::k_stream_count; ++s)
            for (uint32_t slot = 0; slot < 12; ++slot) {
                const size_t i = MltSampler::index(s, slot);
                const double a = x.value(k_seed, i), b = y.value(k_seed, i);
                if (i == t0 || i == t1) {
                    ASSERT_EQ(a, b) << "stream " << s << " slot " << slot;  // the technique is held
                } else if (slot >= x.extent[s]) {
                    // a coordinate x's path did not read is refreshed (then stepped)
                    ASSERT_NE(a, b) << "stream " << s << " slot " << slot;
                } else {
                    ASSERT_NE(a, b) << "stream " << s << " slot " << slot;
                    if (s == MltSampler::camera && slot == 3) d.push_back(wrapped_difference(a, b));
                }
            }
    }
    expect_symmetric_gaussian(d, k_sigma);
}

TEST(Perturbations, TheChoicePerInnerStep) {
    State x = read_state();
    x.sample.t = 2;
    EXPECT_EQ(choose_perturbation(0.0, x), Perturbation::pixel_move);
    EXPECT_EQ(choose_perturbation(std::nextafter(k_pixel_move_probability, 0.0), x), Perturbation::pixel_move);
    EXPECT_EQ(choose_perturbation(k_pixel_move_probability, x), Perturbation::small_step);
    const double lens_from = k_pixel_move_probability + k_small_step_probability;
    EXPECT_EQ(choose_perturbation(std::nextafter(lens_from, 0.0), x), Perturbation::small_step);
    EXPECT_EQ(choose_perturbation(lens_from, x), Perturbation::lens);
    EXPECT_EQ(choose_perturbation(0.999, x), Perturbation::lens);
    x.sample.t = 1;  // light tracing: the caustic perturbation
    EXPECT_EQ(choose_perturbation(0.999, x), Perturbation::caustic);
    EXPECT_EQ(choose_perturbation(0.05, x), Perturbation::pixel_move);
    EXPECT_STREQ(perturbation_name(Perturbation::caustic), "caustic");
}
