// Tests of the building blocks: test RNG, torus wrap, the wrapped Gaussian kernel,
// weighted selection and the statistics helpers the kernel tests rely on.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "toy_targets.h"

namespace cmlt::mcmc {
namespace {

using testing::TestRng;
using testing::Vec;

TEST(TestRng, SameSeedSameStreamDifferentSeedsDiffer) {
  TestRng a(42, 3), b(42, 3), c(42, 4), d(43, 3);
  int same_c = 0, same_d = 0;
  for (int i = 0; i < 1000; ++i) {
    const std::uint64_t va = a.next_u64();
    ASSERT_EQ(va, b.next_u64());
    same_c += va == c.next_u64();
    same_d += va == d.next_u64();
  }
  EXPECT_EQ(same_c, 0);
  EXPECT_EQ(same_d, 0);
}

TEST(TestRng, UniformAndNormalMoments) {
  // 1e6 draws: tolerances are > 6 standard errors.
  TestRng rng(1);
  const int n = 1000000;
  double su = 0, sn = 0, sn2 = 0, mn = 1, mx = 0;
  for (int i = 0; i < n; ++i) {
    const double u = rng.uniform();
    ASSERT_GE(u, 0.0);
    ASSERT_LT(u, 1.0);
    su += u;
    mn = std::min(mn, u);
    mx = std::max(mx, u);
    const double z = rng.normal();
    ASSERT_TRUE(std::isfinite(z));
    sn += z;
    sn2 += z * z;
  }
  EXPECT_NEAR(su / n, 0.5, 6 * std::sqrt(1.0 / 12 / n));
  EXPECT_NEAR(sn / n, 0.0, 6 / std::sqrt(double(n)));
  EXPECT_NEAR(sn2 / n, 1.0, 6 * std::sqrt(2.0 / n));
  EXPECT_LT(mn, 1e-4);
  EXPECT_GT(mx, 1 - 1e-4);
}

TEST(Wrap01, StaysInUnitIntervalAtEdges) {
  const double cases[] = {0.0, 0.25, 1.0, -1.0, 2.75, -0.25, -1e-17, -1e-300, 1.0 - 1e-17,
                          std::nextafter(1.0, 0.0), -std::numeric_limits<double>::denorm_min(),
                          std::numeric_limits<double>::quiet_NaN(), HUGE_VAL, -HUGE_VAL, 1e300};
  for (double v : cases) {
    const double w = wrap01(v);
    EXPECT_GE(w, 0.0) << v;
    EXPECT_LT(w, 1.0) << v;
  }
  EXPECT_DOUBLE_EQ(wrap01(-0.25), 0.75);
  EXPECT_DOUBLE_EQ(wrap01(2.75), 0.75);
  EXPECT_EQ(wrap01(-1e-17), 0.0);  // 1 − 1e-17 rounds to 1: mapped to 0
}

// The wrapped Gaussian's displacement (y − x) mod 1 must have the wrapped-normal law,
// whatever x (also next to the seam): that is what makes T(x→y) = T(y→x) on the torus.
// Chi-square at false-alarm rate 1e-3 per start point.
TEST(WrappedGaussianProposal, DisplacementHasWrappedNormalLawAnywhere) {
  const double sigma = 0.3;  // wide enough that the wrap matters
  const std::size_t bins = 40;
  std::vector<double> probs(bins, 0.0);
  for (std::size_t b = 0; b < bins; ++b)
    for (int m = -10; m <= 10; ++m) {
      const double a = double(b) / bins + m, c = double(b + 1) / bins + m;
      probs[b] += 0.5 * (std::erf(c / (sigma * std::sqrt(2.0))) - std::erf(a / (sigma * std::sqrt(2.0))));
    }
  const WrappedGaussianProposal T{sigma};
  for (double x0 : {0.0, 0.5, 0.999, 0.05}) {
    TestRng rng(9 + testing::seed_offset(), std::uint64_t(x0 * 1000));
    Vec x{x0}, y{0.0};
    std::vector<double> counts(bins, 0.0);
    for (int i = 0; i < 200000; ++i) {
      T.sample(x, y, rng);
      ASSERT_GE(y[0], 0.0);
      ASSERT_LT(y[0], 1.0);
      counts[std::min(bins - 1, std::size_t(wrap01(y[0] - x0) * bins))] += 1;
    }
    double stat;
    int dof;
    const double p = testing::chi_square_p_value(counts, probs, &stat, &dof);
    EXPECT_GT(p, 1e-3) << "x0=" << x0 << " chi2=" << stat << " dof=" << dof;
  }
}

TEST(SelectByTarget, NeverPicksZeroWeight) {
  const double w[] = {0.0, 2.0, 0.0, 1.0, 0.0};
  EXPECT_EQ(detail::select_by_target(w, 5, 0.0), 1u);
  EXPECT_EQ(detail::select_by_target(w, 5, 1.999), 1u);
  EXPECT_EQ(detail::select_by_target(w, 5, 2.0), 3u);
  EXPECT_EQ(detail::select_by_target(w, 5, 3.0), 3u);  // rounding guard: last positive
  EXPECT_EQ(detail::select_by_target(w, 5, 1e300), 3u);
  const double z[] = {0.0, 0.0};
  EXPECT_EQ(detail::select_by_target(z, 2, 0.0), 2u);  // none positive: n
}

TEST(StatisticsHelpers, KnownValues) {
  EXPECT_NEAR(testing::normal_upper_quantile(0.025), 1.959963985, 1e-8);
  EXPECT_NEAR(testing::normal_upper_quantile(1e-3), 3.090232306, 1e-8);
  EXPECT_NEAR(testing::gamma_q(0.5 * 10, 0.5 * 18.307038), 0.05, 1e-6);    // chi2(10) 95%
  EXPECT_NEAR(testing::gamma_q(0.5 * 1, 0.5 * 10.827566), 0.001, 1e-7);    // chi2(1) 99.9%
  EXPECT_NEAR(testing::gamma_q(0.5 * 60, 0.5 * 99.607391), 0.001, 1e-7);   // chi2(60) 99.9%
  // exact bin integrals add up to a closed form
  testing::Binned<testing::TwoBumps> bn{testing::TwoBumps{}, 32};
  EXPECT_NEAR(bn.total(), testing::TwoBumps::integral(0, 1), 1e-14);
  // and agree with a midpoint rule
  double mid = 0;
  const int n = 1000000;
  for (int i = 0; i < n; ++i) mid += testing::TwoBumps::eval((i + 0.5) / n) / n;
  EXPECT_NEAR(mid, bn.total(), 1e-9);
  testing::Binned<testing::CheckerBump> bn2{testing::CheckerBump{}, 8};
  double mid2 = 0;
  const int m = 2000;
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) mid2 += bn2.target.eval((i + 0.5) / m, (j + 0.5) / m) / (double(m) * m);
  EXPECT_NEAR(mid2, bn2.total(), 1e-5);  // cell edges fall on grid lines: O(1/m²)
}

}  // namespace
}  // namespace cmlt::mcmc
