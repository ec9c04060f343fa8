// Chain diagnostics of the Metropolis frames (mcmc/chain_diagnostics.h): the splat
// shares and the stuck-chain count.
#include "mcmc/chain_diagnostics.h"
#include "sampling/rng.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>

namespace cmlt::mcmc {
namespace {

// Stuck-chain statistics: a population of chains whose luminance
// weights are heavy-tailed (Pareto, tail index 0.5: infinite mean) reports one chain far
// above the fair share; an even population exactly the fair share; a chain that
// rejected 1000 proposals in a row counts as stuck whatever its share; stays add up.
TEST(ChainShare, HeavyTailedPopulationHasAHighMaxShare) {
  const size_t n = 2000;
  ShareSummary even, heavy;
  CounterRng rng(7, RngDomain::chain, 0);
  for (size_t c = 0; c < n; ++c) {
    ChainShare a, b;
    a.add(1.0, true);
    a.end_stay();
    b.add(std::pow(1.0 - rng.uniform(), -1.0 / 0.5), true);  // Pareto(alpha = 0.5)
    b.end_stay();
    even.add(a, 10);
    heavy.add(b, 10);
  }
  EXPECT_NEAR(even.max_share(), 1.0 / double(n), 1e-15);
  EXPECT_EQ(even.stuck(), 0u);
  // with alpha = 0.5 the largest of n draws holds a share of order 1
  EXPECT_GT(heavy.max_share(), ShareSummary::k_stuck_factor / double(n));
  EXPECT_GE(heavy.stuck(), 1u);
  EXPECT_LE(heavy.stuck(), n / 10);
}

TEST(ChainShare, LongRejectionRunIsStuckAndStaysAreTracked) {
  ShareSummary s;
  for (int c = 0; c < 4; ++c) {
    ChainShare x;
    x.add(0.25, true);   // the current state's part of a step
    x.add(0.75, false);  // the proposal's
    x.end_stay();        // moved
    x.add(1.0, true);
    x.add(1.0, true);
    x.end_stay();
    EXPECT_DOUBLE_EQ(x.weight, 3.0);
    EXPECT_DOUBLE_EQ(x.max_stay, 2.0);
    s.add(x, c == 2 ? StreakTracker::k_long_streak : 5);
  }
  EXPECT_EQ(s.stuck(), 1u);
  EXPECT_DOUBLE_EQ(s.max_share(), 0.25);
  EXPECT_DOUBLE_EQ(s.max_stay_share(), 2.0 / 12.0);
  // chains that never ran (another part's) do not lower the threshold: of 400 chains
  // 4 splatted, chain 0 with 0.999 of their weight: above 100 / 400, but no share can
  // exceed 100 / 4
  ShareSummary part;
  for (int c = 0; c < 400; ++c) {
    ChainShare x;
    if (c < 4) x.add(c == 0 ? 3000.0 : 1.0, true);
    part.add(x, 0);
  }
  EXPECT_EQ(part.stuck(), 0u);
  EXPECT_EQ(ShareSummary().max_share(), 0.0);
  EXPECT_EQ(ShareSummary().stuck(), 0u);
}

}  // namespace
}  // namespace cmlt::mcmc
