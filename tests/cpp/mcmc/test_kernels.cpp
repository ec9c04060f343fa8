// Statistical and robustness tests of the Metropolis kernels on toy targets with known
// normalisation (STYLE.md §6, "MLT-specific").
//
// Method. Many independent short chains, each started from an exact draw of π = f/∫f
// (rejection sampling). If a kernel leaves π invariant, every chain's state at every
// step is an exact draw of π, so
//  (a) the final states are i.i.d. π: Pearson chi-square against the exact bin masses;
//  (b) with exact expected-value splatting, the splatted weight per bin and step has
//      expectation p_b = ∫_bin f / ∫f exactly; the per-chain averages are i.i.d. across
//      chains, so each bin gets a z-test with the empirical standard error.
// False-alarm rate: 1e-3 per assertion — chi-square p > 1e-3, and for the z-tests a
// Bonferroni threshold z > Φ⁻¹(1 − 1e-3/(2B)) over the B bins. Seeds are fixed, so a
// test either always passes or always fails; the rate says how unlucky a seed would be.
// The seed rule's splats are tested in test_seed_rule.cpp.
#include <gtest/gtest.h>

#include <array>
#include <cstring>
#include <sstream>
#include <vector>

#include "integrators/cmlt/inner_rule.h"
#include "kernel_cases.h"

namespace cmlt::mcmc {
namespace {

using namespace testing;
using coherent::inner_rule_name;
using coherent::inner_step;
using coherent::InnerRule;
using coherent::k_default_inner_rule;
constexpr double k_alpha = 1e-3;

double bonferroni_z(std::size_t bins) { return normal_upper_quantile(k_alpha / (2.0 * double(bins))); }

void record(const std::string& key, double value) {
  ::testing::Test::RecordProperty(key, std::to_string(value));
}

// ---------------------------------------------------------------------------------------
// 1. Invariance and unbiased splatting, 1-D two bumps on a floor (20 bins) and the 2-D
//    checkerboard with bump whose odd cells are zero (8×8 bins, half of them f = 0).
// ---------------------------------------------------------------------------------------
MutationKind stats_kind(Kernel k) {
  switch (k) {
    case Kernel::small_step:
    case Kernel::pssmlt_mixture: return MutationKind::small_step;  // mixture: small steps reported
    case Kernel::large_step: return MutationKind::large_step;
    case Kernel::mtm: return MutationKind::mtm;
    case Kernel::seed: return MutationKind::seed;
    case Kernel::bundle: return MutationKind::bundle;
  }
  return MutationKind::small_step;
}

class KernelOnToyTargets : public ::testing::TestWithParam<KernelParams> {};

template <class Target>
void check_short_chains(const Binned<Target>& bn, const KernelParams& p, std::size_t chains, std::size_t steps,
                        std::uint64_t seed, const char* label) {
  const auto probs = bn.probabilities();
  const ShortChainResult res = run_short_chains(bn, p, chains, steps, seed);
  const ChainStats& st = res.stats[stats_kind(p.kernel)];
  std::printf("[ %s %-22s ] acceptance rate %.3f (mean a %.3f), evaluations/step %.2f\n", label,
              case_name(p).c_str(), st.acceptance_rate(), st.mean_acceptance(),
              double(st.evaluations) / double(std::max<std::uint64_t>(1, st.steps)));
  record(std::string(label) + "_acceptance_rate", st.acceptance_rate());

  // weights: finite, summing to 1 per step
  EXPECT_EQ(res.nonfinite_splats, 0u);
  EXPECT_LT(res.max_weight_error, 1e-12);

  // (a) final states ~ π; bins where f = 0 must stay empty
  for (std::size_t b = 0; b < probs.size(); ++b) {
    if (probs[b] == 0) {
      EXPECT_EQ(res.final_counts[b], 0.0) << "chain entered f = 0 in bin " << b;
      EXPECT_EQ(res.splat_means.mean(b), 0.0) << "weight splatted where f = 0, bin " << b;
    }
  }
  double stat;
  int dof;
  const double pv = chi_square_p_value(res.final_counts, probs, &stat, &dof);
  EXPECT_GT(pv, k_alpha) << label << " final states: chi2 = " << stat << " with " << dof << " dof";

  // (b) splats unbiased (exact rules only)
  if (p.kernel != Kernel::seed) {
    std::size_t worst = 0;
    const double z = res.splat_means.max_abs_z(probs, &worst);
    EXPECT_LT(z, bonferroni_z(probs.size()))
        << label << " splats: bin " << worst << " mean " << res.splat_means.mean(worst) << " ± "
        << res.splat_means.std_error(worst) << " vs " << probs[worst];
  }
}

TEST_P(KernelOnToyTargets, TwoBumps1D_FinalStatesFollowTargetAndSplatsAreUnbiased) {
  const Binned<TwoBumps> bn{TwoBumps{}, 20};
  check_short_chains(bn, GetParam(), 40000, 8, 101, "1d");
}

TEST_P(KernelOnToyTargets, CheckerZero2D_FinalStatesFollowTargetAndSplatsAreUnbiased) {
  const Binned<CheckerBump> bn{CheckerBump{0.0}, 8};
  check_short_chains(bn, GetParam(), 30000, 8, 202, "2d");
}

INSTANTIATE_TEST_SUITE_P(
    Kernels, KernelOnToyTargets,
    ::testing::Values(KernelParams{Kernel::small_step, 1, 0.1}, KernelParams{Kernel::small_step, 1, 0.02},
                      KernelParams{Kernel::large_step, 1, 0.1}, KernelParams{Kernel::pssmlt_mixture, 1, 0.1},
                      KernelParams{Kernel::mtm, 1, 0.1}, KernelParams{Kernel::mtm, 8, 0.1},
                      KernelParams{Kernel::mtm, 4, 0.3}, KernelParams{Kernel::seed, 8, 0.1},
                      KernelParams{Kernel::bundle, 1, 0.1}, KernelParams{Kernel::bundle, 8, 0.1},
                      KernelParams{Kernel::bundle, 3, 0.3}),
    [](const ::testing::TestParamInfo<KernelParams>& info) { return case_name(info.param); });

// ---------------------------------------------------------------------------------------
// 2. Negative controls: the same harness must flag kernels that are wrong.
// ---------------------------------------------------------------------------------------

// A Metropolis chain for π ∝ √f, judged against π ∝ f (a wrong acceptance ratio).
TEST(NegativeControl, WrongAcceptanceRatioIsDetected) {
  const Binned<TwoBumps> bn{TwoBumps{}, 20};
  const auto probs = bn.probabilities();
  auto sqrt_f = [&](const Vec& u) { return std::sqrt(bn.target(u)); };
  const WrappedGaussianProposal T{0.1};
  auto res = run_short_chains(bn, 40000, 8, 303, 1, [&](auto& chain, auto& splat, auto& rng, auto& ws) {
    chain.fx = sqrt_f(chain.x);
    const StepResult r = metropolis_step(chain, sqrt_f, T, splat, rng, ws);
    chain.fx = bn.target(chain.x);
    return r;
  });
  EXPECT_LT(chi_square_p_value(res.final_counts, probs), 1e-6);
  EXPECT_GT(res.splat_means.max_abs_z(probs), 2 * bonferroni_z(probs.size()));
}

// A bundle whose two levels use different widths (centre σ = 0.3, candidates σ = 0.03):
// x and the y_l are then not exchangeable (bundle_step's comment), and it shows.
TEST(NegativeControl, BundleWithMismatchedLevelsIsDetected) {
  const Binned<TwoBumps> bn{TwoBumps{}, 20};
  const auto probs = bn.probabilities();
  const WrappedGaussianProposal Tc{0.3}, Ty{0.03};
  auto res = run_short_chains(bn, 40000, 8, 404, 8, [&](auto& chain, auto& splat, auto& rng, auto& ws) {
    StepResult r;
    Tc.sample(chain.x, ws.centre, rng);
    double total = chain.fx;
    for (std::size_t l = 0; l < ws.tries(); ++l) {
      Ty.sample(ws.centre, ws.y[l], rng);
      ws.fy[l] = bn.target(ws.y[l]);
      total += ws.fy[l];
    }
    splat(chain.x, chain.fx / total);
    r.splatted_weight += chain.fx / total;
    for (std::size_t l = 0; l < ws.tries(); ++l) {
      splat(ws.y[l], ws.fy[l] / total);
      r.splatted_weight += ws.fy[l] / total;
    }
    const double t = rng.uniform() * total;
    if (t >= chain.fx) {
      const std::size_t j = detail::select_by_target(ws.fy.data(), ws.tries(), t - chain.fx);
      std::swap(chain.x, ws.y[j]);
      chain.fx = ws.fy[j];
    }
    return r;
  });
  EXPECT_LT(chi_square_p_value(res.final_counts, probs), 1e-6);
  EXPECT_GT(res.splat_means.max_abs_z(probs), 2 * bonferroni_z(probs.size()));
}

// ---------------------------------------------------------------------------------------
// 3. Zero-contribution regions and hostile targets.
// ---------------------------------------------------------------------------------------
const KernelParams k_all_kernels[] = {
    {Kernel::small_step, 1, 0.1}, {Kernel::large_step, 1, 0.1}, {Kernel::pssmlt_mixture, 1, 0.1},
    {Kernel::mtm, 8, 0.1},        {Kernel::seed, 8, 0.1},       {Kernel::bundle, 8, 0.1}};

// Chains started from the bootstrap on a target that is zero on half the domain: the
// chain never enters f = 0, every splat is finite, positive, on a point with f > 0, and
// the weights of a step sum to 1.
TEST(ZeroRegions, ChainNeverEntersZeroAndNoNaN) {
  const CheckerBump f{0.0};
  for (const auto& p : k_all_kernels) {
    TestRng rng(55, int(p.kernel));
    const auto pool = bootstrap(f, 256, Vec(2, 0.0), rng);
    ASSERT_GT(pool.b.nonzero, 0u);
    auto chains = start_chains(pool, 4, rng);
    Workspace<Vec> ws(p.tries, Vec(2, 0.0));
    std::size_t bad_splats = 0, zero_region_steps = 0;
    ChainStats st;
    auto splat = [&](const Vec& u, double w) {
      if (!(w > 0 && w <= 1 + 1e-12) || !(f(u) > 0)) ++bad_splats;
    };
    for (auto& chain : chains) {
      for (int t = 0; t < 5000; ++t) {
        const StepResult r = do_step(p, chain, f, splat, rng, ws);
        st.record(r);
        ASSERT_NEAR(r.splatted_weight, 1.0, 1e-12) << kernel_name(p.kernel);
        ASSERT_EQ(chain.fx, f(chain.x)) << kernel_name(p.kernel);
        zero_region_steps += !(chain.fx > 0);
      }
    }
    EXPECT_EQ(bad_splats, 0u) << kernel_name(p.kernel);
    EXPECT_EQ(zero_region_steps, 0u) << kernel_name(p.kernel);
    EXPECT_GT(st.zero_values, 0u) << kernel_name(p.kernel) << ": proposals should hit f = 0 regions";
    EXPECT_GT(st.moved, 0u) << kernel_name(p.kernel);
  }
}

// A target that returns NaN, −1 and +Inf on parts of the domain: those values are
// counted as invalid, treated as zero, and never accepted or splatted.
TEST(ZeroRegions, InvalidTargetValuesAreCountedAndTreatedAsZero) {
  auto hostile = [](const Vec& u) {
    if (u[0] < 0.1) return std::numeric_limits<double>::quiet_NaN();
    if (u[0] < 0.2) return -1.0;
    if (u[0] < 0.25) return HUGE_VAL;
    return TwoBumps::eval(u[0]);
  };
  for (const auto& p : k_all_kernels) {
    TestRng rng(77, int(p.kernel));
    auto chain = make_chain(Vec{0.5}, hostile);
    Workspace<Vec> ws(p.tries, Vec(1, 0.0));
    ChainStats st;
    std::size_t bad = 0;
    auto splat = [&](const Vec& u, double w) { bad += !(std::isfinite(w) && w > 0) || u[0] < 0.25; };
    for (int t = 0; t < 20000; ++t) {
      const StepResult r = do_step(p, chain, hostile, splat, rng, ws);
      st.record(r);
      ASSERT_GE(chain.x[0], 0.25) << kernel_name(p.kernel);
      ASSERT_NEAR(r.splatted_weight, 1.0, 1e-12);
    }
    EXPECT_EQ(bad, 0u) << kernel_name(p.kernel);
    EXPECT_GT(st.invalid_values, 0u) << kernel_name(p.kernel);
    EXPECT_LE(st.invalid_values, st.zero_values);
  }
}

// A chain (wrongly) started where f = 0 neither produces NaN nor sticks: it splats x
// with weight 1 until a proposal has f > 0, then moves there.
TEST(ZeroRegions, ChainStartedAtZeroEscapesWithoutNaN) {
  const CheckerBump f{0.0};
  for (const auto& p : k_all_kernels) {
    TestRng rng(88, int(p.kernel));
    auto chain = make_chain(Vec{0.3, 0.1}, f);  // odd cell (1, 0): f = 0
    ASSERT_EQ(chain.fx, 0.0);
    Workspace<Vec> ws(p.tries, Vec(2, 0.0));
    std::size_t nonfinite = 0;
    auto splat = [&](const Vec&, double w) { nonfinite += !std::isfinite(w); };
    int t = 0;
    for (; t < 1000 && !(chain.fx > 0); ++t) {
      const StepResult r = do_step(p, chain, f, splat, rng, ws);
      ASSERT_NEAR(r.splatted_weight, 1.0, 1e-12);
    }
    EXPECT_GT(chain.fx, 0.0) << kernel_name(p.kernel) << " stuck in the zero region";
    EXPECT_EQ(nonfinite, 0u);
  }
}

// ---------------------------------------------------------------------------------------
// 4. Determinism and bit-exact rejects.
// ---------------------------------------------------------------------------------------
struct Trace {
  std::vector<double> values;  // states, f values, splat states and weights, in order
  bool operator==(const Trace& o) const {
    return values.size() == o.values.size() &&
           std::memcmp(values.data(), o.values.data(), values.size() * sizeof(double)) == 0;
  }
};

Trace run_trace(const KernelParams& p, std::uint64_t seed, int steps) {
  const CheckerBump f{0.25};
  TestRng rng(seed);
  auto chain = make_chain(Vec{0.7, 0.3}, f);
  Workspace<Vec> ws(p.tries, chain.x);
  Trace tr;
  auto splat = [&](const Vec& u, double w) {
    tr.values.insert(tr.values.end(), u.begin(), u.end());
    tr.values.push_back(w);
  };
  for (int t = 0; t < steps; ++t) {
    const Vec before = chain.x;
    const double f_before = chain.fx;
    const StepResult r = do_step(p, chain, f, splat, rng, ws);
    if (!r.moved) {
      // reject restores the state bit for bit
      EXPECT_EQ(std::memcmp(before.data(), chain.x.data(), before.size() * sizeof(double)), 0);
      EXPECT_EQ(std::memcmp(&f_before, &chain.fx, sizeof(double)), 0);
    } else {
      EXPECT_EQ(chain.fx, f(chain.x));  // the carried f* belongs to the new state
    }
    tr.values.insert(tr.values.end(), chain.x.begin(), chain.x.end());
    tr.values.push_back(chain.fx);
  }
  return tr;
}

TEST(Determinism, SameSeedSameChainDifferentSeedDifferentChain) {
  for (const auto& p : k_all_kernels) {
    const Trace a = run_trace(p, 2024, 3000), b = run_trace(p, 2024, 3000), c = run_trace(p, 2025, 3000);
    EXPECT_TRUE(a == b) << kernel_name(p.kernel);
    EXPECT_FALSE(a == c) << kernel_name(p.kernel);
  }
}

// ---------------------------------------------------------------------------------------
// 5. Generic State types and the statistics records.
// ---------------------------------------------------------------------------------------
TEST(Generic, FixedSizeArrayStateWorksWithEveryKernel) {
  using State = std::array<double, 2>;
  const CheckerBump f{0.25};
  TestRng rng(5);
  auto chain = make_chain(State{0.7, 0.3}, f);
  Workspace<State> ws(4, chain.x);
  const WrappedGaussianProposal T{0.1};
  double weight = 0;
  auto splat = [&](const State& u, double w) {
    EXPECT_GE(u[0], 0.0);
    EXPECT_LT(u[1], 1.0);
    weight += w;
  };
  KernelStats stats;
  for (int t = 0; t < 1000; ++t) {
    stats.record(metropolis_step(chain, f, T, splat, rng, ws));
    stats.record(large_step(chain, f, splat, rng, ws));
    stats.record(mtm_step(chain, f, T, splat, rng, ws));
    stats.record(inner_step(InnerRule::seed, chain, f, T, splat, rng, ws));
    stats.record(bundle_step(chain, f, T, splat, rng, ws));
  }
  EXPECT_NEAR(weight, 5000.0, 1e-9);
  for (std::size_t i = 0; i < k_mutation_kind_count; ++i) EXPECT_EQ(stats.per_kind[i].steps, 1000u);
}

// A non-symmetric proposal takes the Hastings ratio: an independence sampler with a
// linear density q(y) = 2y on [0,1) must still leave π invariant.
struct LinearIndependenceProposal {
  static constexpr bool k_symmetric = false;
  template <class State, class Rng>
  void sample(const State&, State& to, Rng& rng) const {
    to[0] = std::sqrt(rng.uniform());
  }
  template <class State>
  double density(const State&, const State& to) const { return 2.0 * to[0]; }
};

TEST(Generic, NonSymmetricProposalUsesHastingsRatio) {
  const Binned<TwoBumps> bn{TwoBumps{}, 20};
  const auto probs = bn.probabilities();
  const LinearIndependenceProposal q;
  auto res = run_short_chains(bn, 40000, 8, 606, 1, [&](auto& chain, auto& splat, auto& rng, auto& ws) {
    return metropolis_step(chain, bn.target, q, splat, rng, ws);
  });
  EXPECT_GT(chi_square_p_value(res.final_counts, probs), k_alpha);
  EXPECT_LT(res.splat_means.max_abs_z(probs), bonferroni_z(probs.size()));
}

TEST(Stats, RecordMergeAndJson) {
  KernelStats a, b;
  StepResult r;
  r.kind = MutationKind::mtm;
  r.moved = true;
  r.acceptance = 0.75;
  r.evaluations = 15;
  r.splats = 2;
  a.record(r);
  r.moved = false;
  r.acceptance = 0.25;
  b.record(r);
  a.merge(b);
  const ChainStats& s = a[MutationKind::mtm];
  EXPECT_EQ(s.steps, 2u);
  EXPECT_EQ(s.moved, 1u);
  EXPECT_EQ(s.evaluations, 30u);
  EXPECT_DOUBLE_EQ(s.acceptance_rate(), 0.5);
  EXPECT_DOUBLE_EQ(s.mean_acceptance(), 0.5);
  EXPECT_EQ(ChainStats{}.acceptance_rate(), 0.0);  // no 0/0
  std::ostringstream os;
  a.write_json(os);
  EXPECT_EQ(os.str(),
            "{\"mtm\": {\"steps\": 2, \"moved\": 1, \"acceptance_rate\": 0.5, \"mean_acceptance\": 0.5, "
            "\"evaluations\": 30, \"zero_values\": 0, \"invalid_values\": 0, \"splats\": 4}}");
  EXPECT_STREQ(mutation_kind_name(MutationKind::bundle), "bundle");
  EXPECT_STREQ(inner_rule_name(k_default_inner_rule), "bundle");
}

// Cost per step on a target without zeros: MTM traces 2k − 1 new paths, the bundle k,
// the single-proposal steps 1; and the per-step records add up.
TEST(Stats, EvaluationsPerStep) {
  const TwoBumps f;
  for (std::size_t k : {1u, 2u, 8u}) {
    for (const Kernel kernel : {Kernel::small_step, Kernel::large_step, Kernel::mtm, Kernel::seed, Kernel::bundle}) {
      const KernelParams p{kernel, k, 0.1};
      TestRng rng(9);
      auto chain = make_chain(Vec{0.3}, f);
      Workspace<Vec> ws(k, chain.x);
      auto splat = [](const Vec&, double) {};
      ChainStats st;
      for (int t = 0; t < 100; ++t) {
        const StepResult r = do_step(p, chain, f, splat, rng, ws);
        st.record(r);
        const std::size_t expected = kernel == Kernel::mtm || kernel == Kernel::seed ? 2 * k - 1
                                     : kernel == Kernel::bundle                       ? k
                                                                                      : 1;
        ASSERT_EQ(r.evaluations, expected) << kernel_name(kernel) << " k=" << k;
        ASSERT_EQ(r.zero_values, 0u);
        ASSERT_EQ(r.moved, r.chosen != 0);
        ASSERT_GE(r.acceptance, 0.0);
        ASSERT_LE(r.acceptance, 1.0);
      }
      EXPECT_EQ(st.steps, 100u);
      EXPECT_GT(st.moved, 0u);
    }
  }
}

// ---------------------------------------------------------------------------------------
// 6. The two halves of a step (coherent MLT's chains in lockstep, cmlt_chain.h): several
//    chains drawing their points first, the points evaluated together, then each chain
//    finishing, take the same steps and splats as whole steps one chain at a time.
// ---------------------------------------------------------------------------------------
TEST(Halves, InterleavedChainsMatchWholeStepsBitForBit) {
  using State = std::array<double, 2>;
  const CheckerBump f{0.25};
  const WrappedGaussianProposal T{0.1};
  constexpr int kChains = 5, kBlocks = 400, kInner = 3;
  struct Run {
    std::vector<double> splats;  // per chain: (u0, u1, w) of every splat, in order
    std::vector<State> final_states;
  };
  const auto start = [](int c) { return State{0.05 + 0.17 * c, 0.9 - 0.13 * c}; };
  // whole steps, one chain after another
  std::vector<Run> whole(kChains);
  for (int c = 0; c < kChains; ++c) {
    TestRng rng(77, c);
    auto chain = make_chain(start(c), f);
    Workspace<State> ws(3, chain.x);
    auto splat = [&](const State& u, double w) { whole[c].splats.insert(whole[c].splats.end(), {u[0], u[1], w}); };
    for (int b = 0; b < kBlocks; ++b) {
      large_step(chain, f, splat, rng, ws);
      for (int i = 0; i < kInner; ++i) bundle_step(chain, f, T, splat, rng, ws);
    }
    whole[c].final_states.push_back(chain.x);
  }
  // halves, the chains in lockstep
  std::vector<Run> halves(kChains);
  std::vector<TestRng> rngs;
  std::vector<Chain<State>> chains;
  std::vector<Workspace<State>> wss;
  for (int c = 0; c < kChains; ++c) {
    rngs.emplace_back(77, c);
    chains.push_back(make_chain(start(c), f));
    wss.emplace_back(3, chains.back().x);
  }
  int evaluated = 0;  // evaluations between the halves, counted by a target that must not be called after
  for (int b = 0; b < kBlocks; ++b)
    for (int phase = 0; phase <= kInner; ++phase) {
      for (int c = 0; c < kChains; ++c) {
        if (phase == 0) metropolis_draw(chains[c], UniformProposal{}, rngs[c], wss[c]);
        else bundle_draw(chains[c], T, rngs[c], wss[c]);
      }
      for (int c = 0; c < kChains; ++c) {
        auto splat = [&](const State& u, double w) {
          halves[c].splats.insert(halves[c].splats.end(), {u[0], u[1], w});
        };
        const StepResult r = phase == 0 ? metropolis_finish(chains[c], f, UniformProposal{}, splat, rngs[c], wss[c],
                                                            MutationKind::large_step)
                                        : bundle_finish(chains[c], f, splat, rngs[c], wss[c]);
        evaluated += int(r.evaluations);
      }
    }
  for (int c = 0; c < kChains; ++c) {
    halves[c].final_states.push_back(chains[c].x);
    ASSERT_EQ(whole[c].splats.size(), halves[c].splats.size()) << "chain " << c;
    EXPECT_EQ(std::memcmp(whole[c].splats.data(), halves[c].splats.data(), whole[c].splats.size() * sizeof(double)), 0)
        << "chain " << c;
    EXPECT_EQ(whole[c].final_states[0], halves[c].final_states[0]) << "chain " << c;
  }
  EXPECT_EQ(evaluated, kChains * kBlocks * (1 + 3 * kInner));
  // the chains moved (the comparison is not between two frozen chains)
  for (int c = 0; c < kChains; ++c) EXPECT_NE(halves[c].final_states[0], start(c)) << "chain " << c;
}

TEST(Workspace, RejectsZeroTries) {
  EXPECT_THROW(Workspace<Vec>(0, Vec(1)), std::invalid_argument);
}

}  // namespace
}  // namespace cmlt::mcmc
