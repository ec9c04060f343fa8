// The seminar's ("seed") splatting rule for multiple-try Metropolis against the two exact
// rules, on the 1-D two-bumps target (DESIGN.md §3 asks to reproduce its first check).
//
// The seed rule splats every candidate y_l with a·f*(y_l)/F_y and every reference point
// z_l with (1−a)·f*(z_l)/F_z. The chain itself is the ordinary MTM chain (same random
// numbers, same moves); only the splats differ. The z_l are drawn around y*, not x, so
// the rejected share of the weight is smeared out by one extra proposal width.
// Measured (σ = 0.1, k = 8): the bias sharpens π — bumps ~+10%, floor ~−18% — because
// each local set is reweighted by f*, and one acceptance a (of the chosen y*) is applied to
// every candidate. These tests RECORD the numbers (RecordProperty + stdout) and assert
// what the evidence supports: the seed rule stays above an error floor that both exact
// rules go below, its short-chain splats differ from π by many standard errors, and it
// coincides with the exact rule only for k = 1.
#include <gtest/gtest.h>


#include "integrators/cmlt/inner_rule.h"
#include "kernel_cases.h"

namespace cmlt::mcmc {
namespace {

using namespace testing;
using coherent::inner_rule_name;
using coherent::inner_step;
using coherent::InnerRule;
using coherent::k_default_inner_rule;

void record(const std::string& key, double value) {
  ::testing::Test::RecordProperty(key, std::to_string(value));
}

// Long single chains: L1 = Σ_b |ĥ_b − p_b| over 32 bins after 20k, 80k and 320k steps,
// averaged over 8 independent chains (each started from an exact draw of π).
TEST(SeedRule, L1ErrorStallsWhileExactRulesConverge) {
  const Binned<TwoBumps> bn{TwoBumps{}, 32};
  const auto probs = bn.probabilities();
  const WrappedGaussianProposal T{0.1};
  constexpr std::size_t k_tries = 8, k_replicates = 8;
  constexpr std::size_t k_snapshots[3] = {20000, 80000, 320000};
  const InnerRule rules[3] = {InnerRule::seed, InnerRule::mtm, InnerRule::bundle};
  double l1[3][3] = {};
  ChainStats stats[3];

  for (int ri = 0; ri < 3; ++ri) {
    for (std::size_t rep = 0; rep < k_replicates; ++rep) {
      TestRng rng(31337 + seed_offset(), rep);  // the same seeds for every rule
      auto chain = make_chain(bn.exact_draw(rng), bn.target);
      Workspace<Vec> ws(k_tries, chain.x);
      std::vector<double> h(bn.bins(), 0.0);
      auto splat = [&](const Vec& u, double w) { h[bn.bin(u)] += w; };
      std::size_t snap = 0;
      for (std::size_t n = 1; n <= k_snapshots[2]; ++n) {
        stats[ri].record(inner_step(rules[ri], chain, bn.target, T, splat, rng, ws));
        if (n == k_snapshots[snap]) {
          double e = 0;
          for (std::size_t b = 0; b < h.size(); ++b) e += std::abs(h[b] / double(n) - probs[b]);
          l1[ri][snap++] += e / double(k_replicates);
        }
      }
    }
  }

  std::printf("\n[ seed-rule study ] two bumps, wrapped Gaussian sigma=0.1, k=8, 32 bins, mean of 8 chains\n");
  std::printf("  rule     L1@20k   L1@80k   L1@320k  slope   acceptance  evaluations/step\n");
  double slope[3];
  for (int ri = 0; ri < 3; ++ri) {
    slope[ri] = std::log(l1[ri][2] / l1[ri][0]) / std::log(16.0);
    std::printf("  %-7s  %.4f   %.4f   %.4f   %+.2f   %.3f       %.1f\n", inner_rule_name(rules[ri]), l1[ri][0],
                l1[ri][1], l1[ri][2], slope[ri], stats[ri].acceptance_rate(),
                double(stats[ri].evaluations) / double(stats[ri].steps));
    for (int s = 0; s < 3; ++s)
      record(std::string("L1_") + inner_rule_name(rules[ri]) + "_" + std::to_string(k_snapshots[s]), l1[ri][s]);
    record(std::string("acceptance_") + inner_rule_name(rules[ri]), stats[ri].acceptance_rate());
  }

  // exact rules: error falls about as 1/sqrt(n) (slope −0.5); allow anything below −0.25
  EXPECT_LT(slope[1], -0.25) << "mtm L1 does not converge";
  EXPECT_LT(slope[2], -0.25) << "bundle L1 does not converge";
  // seed rule: stalls (slope near 0) at a floor well above both exact rules at 320k
  EXPECT_GT(slope[0], -0.1) << "seed rule converges after all: revisit DESIGN.md §3";
  EXPECT_GT(l1[0][2], 3.0 * std::max(l1[1][2], l1[2][2])) << "seed rule error is not above the exact rules";
}

// Short chains from exact draws, paired: the seed and mtm rules consume the same random
// numbers, so their chains are identical and only the splats differ. The mtm splats
// match π (z-test), the seed splats do not. False-alarm rate 1e-3 (Bonferroni, 32 bins).
TEST(SeedRule, ShortChainSplatBiasIsMeasured) {
  const Binned<TwoBumps> bn{TwoBumps{}, 32};
  const auto probs = bn.probabilities();
  const double zcrit = normal_upper_quantile(1e-3 / (2.0 * 32));
  const auto seed = run_short_chains(bn, KernelParams{Kernel::seed, 8, 0.1}, 40000, 8, 777);
  const auto mtm = run_short_chains(bn, KernelParams{Kernel::mtm, 8, 0.1}, 40000, 8, 777);
  ASSERT_EQ(seed.final_counts, mtm.final_counts);  // same chains

  std::printf("\n[ seed-rule bias ] splatted mass per bin vs exact (40000 chains x 8 steps, sigma=0.1, k=8)\n");
  std::printf("  bin  x-range          exact     seed      rel.bias   z(seed)   z(mtm)\n");
  double worst_rel = 0, peak_rel = 0, l1_seed = 0, l1_mtm = 0;
  std::size_t peak_bin = 0;
  for (std::size_t b = 0; b < probs.size(); ++b) {
    if (probs[b] > probs[peak_bin]) peak_bin = b;
    const double rel = seed.splat_means.mean(b) / probs[b] - 1.0;
    const double zs = (seed.splat_means.mean(b) - probs[b]) / seed.splat_means.std_error(b);
    const double zm = (mtm.splat_means.mean(b) - probs[b]) / mtm.splat_means.std_error(b);
    l1_seed += std::abs(seed.splat_means.mean(b) - probs[b]);
    l1_mtm += std::abs(mtm.splat_means.mean(b) - probs[b]);
    if (std::abs(rel) > std::abs(worst_rel)) worst_rel = rel;
    if (std::abs(zs) > 3 || b % 4 == 0)
      std::printf("  %2zu   [%.3f,%.3f)    %.5f   %.5f   %+6.2f%%   %+7.1f   %+5.1f\n", b, b / 32.0, (b + 1) / 32.0,
                  probs[b], seed.splat_means.mean(b), 100 * rel, zs, zm);
  }
  peak_rel = seed.splat_means.mean(peak_bin) / probs[peak_bin] - 1.0;
  std::printf("  peak bin %zu: seed splats %+.2f%% of exact; worst bin %+.2f%%; L1 of mean seed %.4f, mtm %.4f\n",
              peak_bin, 100 * peak_rel, 100 * worst_rel, l1_seed, l1_mtm);
  record("seed_peak_relative_bias", peak_rel);
  record("seed_worst_relative_bias", worst_rel);
  record("seed_bias_L1", l1_seed);
  record("mtm_bias_L1", l1_mtm);

  EXPECT_LT(mtm.splat_means.max_abs_z(probs), zcrit) << "the exact mtm rule fails its own z-test";
  EXPECT_GT(seed.splat_means.max_abs_z(probs), zcrit) << "seed rule bias not detected";
  EXPECT_GT(l1_seed, 5 * l1_mtm);
  // Direction, as measured: the seed rule SHARPENS π — too much mass on the bumps, too
  // little on the floor (reweighting each local set by f* concentrates it on the modes).
  // DESIGN.md §3 reported the opposite sign ("peak about 3% low"); that is not reproduced
  // here, nor for any sigma in 0.005..0.2 with k = 2 or 8 (see the commit message).
  EXPECT_GT(peak_rel, 0.0) << "seed rule now puts too little mass on the peak: re-read DESIGN.md §3";
  EXPECT_LT(seed.splat_means.mean(15) / probs[15] - 1.0, 0.0) << "floor between the bumps";
}

// With k = 1 the seed rule is the mtm rule ({y_1} = {y*}, {z_1} = {x}): identical splats.
TEST(SeedRule, EqualsExactRuleForOneTry) {
  const Binned<TwoBumps> bn{TwoBumps{}, 32};
  const auto seed = run_short_chains(bn, KernelParams{Kernel::seed, 1, 0.1}, 2000, 8, 778);
  const auto mtm = run_short_chains(bn, KernelParams{Kernel::mtm, 1, 0.1}, 2000, 8, 778);
  EXPECT_EQ(seed.splat_means.sum, mtm.splat_means.sum);
  EXPECT_EQ(seed.final_counts, mtm.final_counts);
}

}  // namespace
}  // namespace cmlt::mcmc

namespace cmlt::mcmc {
namespace {

// The same paired measurement on the 2-D checkerboard with bump (odd cells 0.25, 8×8 bins):
// the bias is not a 1-D artefact. Bonferroni over 64 bins at 1e-3.
TEST(SeedRule, ShortChainSplatBiasIn2D) {
  using namespace testing;
  const Binned<CheckerBump> bn{CheckerBump{0.25}, 8};
  const auto probs = bn.probabilities();
  const double zcrit = normal_upper_quantile(1e-3 / (2.0 * 64));
  const auto seed = run_short_chains(bn, KernelParams{Kernel::seed, 8, 0.1}, 30000, 8, 779);
  const auto mtm = run_short_chains(bn, KernelParams{Kernel::mtm, 8, 0.1}, 30000, 8, 779);
  double l1_seed = 0, l1_mtm = 0;
  std::size_t bump_bin = bn.bin(Vec{0.7, 0.3});
  for (std::size_t b = 0; b < probs.size(); ++b) {
    l1_seed += std::abs(seed.splat_means.mean(b) - probs[b]);
    l1_mtm += std::abs(mtm.splat_means.mean(b) - probs[b]);
  }
  const double bump_rel = seed.splat_means.mean(bump_bin) / probs[bump_bin] - 1.0;
  std::printf("[ seed-rule bias 2d ] L1 of mean splats: seed %.4f, mtm %.4f; bump bin %+.2f%%; max|z| seed %.1f, "
              "mtm %.1f (critical %.2f)\n",
              l1_seed, l1_mtm, 100 * bump_rel, seed.splat_means.max_abs_z(probs), mtm.splat_means.max_abs_z(probs),
              zcrit);
  ::testing::Test::RecordProperty("seed_bias_L1_2d", std::to_string(l1_seed));
  ::testing::Test::RecordProperty("seed_bump_relative_bias_2d", std::to_string(bump_rel));
  EXPECT_LT(mtm.splat_means.max_abs_z(probs), zcrit);
  EXPECT_GT(seed.splat_means.max_abs_z(probs), zcrit);
  EXPECT_GT(l1_seed, 2 * l1_mtm);  // the mtm L1 here is pure noise (64 bins), about 0.017
}

}  // namespace
}  // namespace cmlt::mcmc
