// Normalisation b = E[f*] and chain starts by resampling the bootstrap pool ∝ f*.
// False-alarm rates are stated per assertion; seeds are fixed.
#include <gtest/gtest.h>

#include <limits>

#include "kernel_cases.h"

namespace cmlt::mcmc {
namespace {

using namespace testing;

// Σ of f² on a fine midpoint grid: the exact variance of f under the uniform density.
double two_bumps_variance() {
  const int n = 1000000;
  double s = 0;
  for (int i = 0; i < n; ++i) {
    const double v = TwoBumps::eval((i + 0.5) / n);
    s += v * v / n;
  }
  const double b = TwoBumps::integral(0, 1);
  return s - b * b;
}

TEST(Bootstrap, RecoversNormalisationWithinItsStandardError) {
  TestRng rng(11 + seed_offset());
  const auto pool = bootstrap(TwoBumps{}, 200000, Vec(1, 0.0), rng);
  const double b = TwoBumps::integral(0, 1);
  ASSERT_EQ(pool.states.size(), 200000u);
  EXPECT_EQ(pool.b.samples, 200000u);
  EXPECT_EQ(pool.b.nonzero, 200000u);
  // |error| < 4 SE: false-alarm rate 6e-5
  EXPECT_LT(std::abs(pool.b.mean - b), 4 * pool.b.std_error) << pool.b.mean << " vs " << b;
  // the reported SE matches the exact sd/√N (its own relative sd is ~0.3% here)
  const double se_exact = std::sqrt(two_bumps_variance() / 200000.0);
  EXPECT_NEAR(pool.b.std_error / se_exact, 1.0, 0.02);
  std::printf("[ bootstrap ] b = %.6f ± %.6f (exact %.6f, exact SE %.6f)\n", pool.b.mean, pool.b.std_error, b,
              se_exact);
}

// 95% intervals from 1000 independent bootstraps of N = 1000 cover b about 95% of the
// time: accepted range [0.92, 0.98] (±4.4 binomial sd).
TEST(Bootstrap, ConfidenceIntervalCoverage) {
  const double b = TwoBumps::integral(0, 1);
  int covered = 0;
  for (int r = 0; r < 1000; ++r) {
    TestRng rng(12 + seed_offset(), r);
    const auto pool = bootstrap(TwoBumps{}, 1000, Vec(1, 0.0), rng);
    covered += pool.b.lower() <= b && b <= pool.b.upper();
  }
  std::printf("[ bootstrap ] 95%% CI coverage %.3f\n", covered / 1000.0);
  EXPECT_GE(covered, 920);
  EXPECT_LE(covered, 980);
}

TEST(NormalisationAccumulator, MergeEqualsSequentialAndSanitises) {
  TestRng rng(13);
  NormalisationAccumulator all, a, b;
  for (int i = 0; i < 10000; ++i) {
    const double v = TwoBumps::eval(rng.uniform());
    all.add(v);
    (i < 3000 ? a : b).add(v);
  }
  a.merge(b);
  EXPECT_NEAR(a.estimate().mean, all.estimate().mean, 1e-13);
  EXPECT_NEAR(a.estimate().std_error, all.estimate().std_error, 1e-13);
  EXPECT_EQ(a.estimate().samples, 10000u);
  NormalisationAccumulator empty, bad;
  EXPECT_EQ(empty.estimate().mean, 0.0);
  EXPECT_EQ(empty.estimate().std_error, 0.0);  // no 0/0
  bad.add(std::numeric_limits<double>::quiet_NaN());
  bad.add(-2.0);
  bad.add(HUGE_VAL);
  bad.add(3.0);
  EXPECT_DOUBLE_EQ(bad.estimate().mean, 0.75);
  EXPECT_EQ(bad.estimate().nonzero, 1u);
  empty.merge(bad);
  EXPECT_DOUBLE_EQ(empty.estimate().mean, 0.75);
}

// Resampled indices follow the weights (chi-square, false-alarm 1e-3) and never pick a
// zero weight; bad weights are rejected with a message.
TEST(Resample, FrequenciesFollowWeightsAndZerosAreNeverChosen) {
  const std::vector<double> w = {0.0, 1.0, 3.0, 0.0, 0.5, 2.5, 0.0};
  TestRng rng(14 + seed_offset());
  const auto idx = resample_start_indices(w, 100000, rng);
  std::vector<double> counts(w.size(), 0.0), probs(w.size());
  for (auto i : idx) counts[i] += 1;
  for (std::size_t i = 0; i < w.size(); ++i) {
    probs[i] = w[i] / 7.0;
    if (w[i] == 0) {
      EXPECT_EQ(counts[i], 0.0);
    }
  }
  EXPECT_GT(chi_square_p_value(counts, probs), 1e-3);

  EXPECT_THROW(resample_start_indices(std::vector<double>{0.0, 0.0}, 1, rng), std::invalid_argument);
  EXPECT_THROW(resample_start_indices(std::vector<double>{}, 1, rng), std::invalid_argument);
  EXPECT_THROW(resample_start_indices(std::vector<double>{1.0, -1.0}, 1, rng), std::invalid_argument);
  EXPECT_THROW(resample_start_indices(std::vector<double>{1.0, std::nan("")}, 1, rng), std::invalid_argument);
  EXPECT_THROW(resample_start_states(std::vector<Vec>(2, Vec{0.5}), std::vector<double>{1.0}, 1, rng),
               std::invalid_argument);
  const auto states = resample_start_states(std::vector<Vec>{Vec{0.1}, Vec{0.9}}, std::vector<double>{0.0, 1.0}, 5, rng);
  ASSERT_EQ(states.size(), 5u);
  for (const auto& s : states) EXPECT_EQ(s[0], 0.9);
}

// The start-up bias elimination is exact for any pool size: with b̂ from a pool of only
// N = 4 uniform samples, one chain resampled from it and run for L = 8 steps,
//   E[ b̂ · (splatted weight in bin j) / L ] = ∫_bin j f.
// 100000 replicates, z-test per bin (Bonferroni over 16 bins, 1e-3), for mtm and bundle
// and for the resampled start alone (L = 0). Then the negative control: a chain started
// at a uniform draw (no resampling) with the exact b shows start-up bias.
struct StartCase {
  const char* name;
  Kernel kernel;
  std::size_t steps;
  bool resample;
};

BinMeans run_started_chains(const StartCase& sc, std::size_t replicates, std::uint64_t seed) {
  const Binned<TwoBumps> bn{TwoBumps{}, 16};
  const KernelParams p{sc.kernel, 8, 0.05};
  const double b_exact = bn.total();
  BinMeans means(bn.bins());
  Workspace<Vec> ws(p.tries, Vec(1, 0.0));
  std::vector<double> h(bn.bins());
  auto splat = [&](const Vec& u, double w) { h[bn.bin(u)] += w; };
  for (std::size_t r = 0; r < replicates; ++r) {
    TestRng rng(seed + seed_offset(), r);
    std::fill(h.begin(), h.end(), 0.0);
    double b_hat;
    Chain<Vec> chain;
    if (sc.resample) {
      const auto pool = bootstrap(bn.target, 4, Vec(1, 0.0), rng);
      b_hat = pool.b.mean;
      chain = start_chains(pool, 1, rng)[0];
    } else {
      b_hat = b_exact;
      chain = make_chain(Vec{rng.uniform()}, bn.target);
    }
    if (sc.steps == 0) {
      h[bn.bin(chain.x)] = 1.0;
    } else {
      for (std::size_t t = 0; t < sc.steps; ++t) do_step(p, chain, bn.target, splat, rng, ws);
      for (double& v : h) v /= double(sc.steps);
    }
    for (double& v : h) v *= b_hat;
    means.add(h);
  }
  return means;
}

TEST(Resample, BootstrapStartedChainsAreUnbiasedForAnyPoolSize) {
  const Binned<TwoBumps> bn{TwoBumps{}, 16};
  const auto integrals = bn.bin_integrals();
  const double zcrit = normal_upper_quantile(1e-3 / (2.0 * 16));
  const StartCase cases[] = {{"resampled start only", Kernel::mtm, 0, true},
                             {"resampled + 8 mtm steps", Kernel::mtm, 8, true},
                             {"resampled + 8 bundle steps", Kernel::bundle, 8, true},
                             {"resampled + 8 small steps", Kernel::small_step, 8, true}};
  for (const auto& sc : cases) {
    const BinMeans m = run_started_chains(sc, 100000, 15);
    std::size_t worst = 0;
    const double z = m.max_abs_z(integrals, &worst);
    std::printf("[ unbiased start ] %-28s max|z| = %.2f (critical %.2f)\n", sc.name, z, zcrit);
    EXPECT_LT(z, zcrit) << sc.name << ": bin " << worst << " " << m.mean(worst) << " ± " << m.std_error(worst)
                        << " vs " << integrals[worst];
  }
}

TEST(NegativeControl, UniformStartWithoutResamplingShowsStartUpBias) {
  const Binned<TwoBumps> bn{TwoBumps{}, 16};
  const auto integrals = bn.bin_integrals();
  const double zcrit = normal_upper_quantile(1e-3 / (2.0 * 16));
  const BinMeans m = run_started_chains({"uniform start + 8 small steps", Kernel::small_step, 8, false}, 100000, 16);
  const double z = m.max_abs_z(integrals);
  std::printf("[ negative control ] uniform start + 8 small steps: max|z| = %.2f\n", z);
  EXPECT_GT(z, 2 * zcrit);
}

}  // namespace
}  // namespace cmlt::mcmc
