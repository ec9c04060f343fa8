// The toy harness (short chains from exact draws, final states and splats against the
// exact bin masses; see test_kernels.cpp) driving coherent MLT's real proposals
// (integrators/cmlt/perturbations.h) on its real chain state (a key plus overrides,
// cmlt_state.h): a 2-D checkerboard-with-bump target over the film coordinates of the
// state. If a perturbation were not symmetric (or moved coordinates it should not), the
// bundle and multiple-try rules, which assume T(x→y) = T(y→x), would stop leaving π
// invariant and these tests would fail. Also the kernels' batch hook, which the bundle
// evaluator relies on: every point of a bundle is drawn, handed to prepare() once, and
// only then evaluated.
//
// False-alarm rate 1e-3 per assertion (Bonferroni over the bins for the z-tests).
#include <gtest/gtest.h>

#include <cstdio>
#include <vector>

#include "integrators/cmlt/inner_rule.h"
#include "integrators/cmlt/perturbations.h"
#include "kernel_cases.h"

namespace cmlt::mcmc {
namespace {

using namespace testing;
using coherent::film_index;
using coherent::InnerRule;
using coherent::Perturbation;
using coherent::PerturbationProposal;
using coherent::State;
using coherent::StateKey;
constexpr double k_alpha = 1e-3;
constexpr uint64_t k_key_seed = 5;

/// The checkerboard with bump over the state's film position.
struct FilmTarget {
  Binned<CheckerBump> bn{CheckerBump{0.25}, 8};
  double operator()(const State& s) const {
    // the path reads the film position, camera slots 0 and 1 (the extent the small step
    // keeps, as PointSampler records it for the renderer's target)
    s.extent = {2, 0, 0};
    return bn.target.eval(s.value(k_key_seed, film_index(0)), s.value(k_key_seed, film_index(1)));
  }
  std::size_t bin(const State& s) const {
    return bn.bin(Vec{s.value(k_key_seed, film_index(0)), s.value(k_key_seed, film_index(1))});
  }
};

/// An exact draw of π as a state: a fresh key, the film position overridden.
State exact_state(const FilmTarget& f, TestRng& rng, uint32_t id) {
  const Vec u = f.bn.exact_draw(rng);
  State s;
  s.key = StateKey{RngDomain::test, id, 1};
  s.set(film_index(0), u[0]);
  s.set(film_index(1), u[1]);
  return s;
}

void check_real_proposal(Perturbation kind, InnerRule rule, std::size_t tries, std::uint64_t seed) {
  const FilmTarget f;
  // σ 0.1 in primary units on both film axes (1×1 "image"); small steps: σ 0.1 too
  const std::size_t bins = f.bn.bins(), chains = 12000, steps = 6;
  const auto probs = f.bn.probabilities();
  std::vector<double> final_counts(bins, 0.0), h(bins, 0.0);
  BinMeans splat_means(bins);
  Workspace<State> ws(tries, State{});
  auto splat = [&](const State& s, double w) { h[f.bin(s)] += w; };
  KernelStats stats;
  for (std::size_t c = 0; c < chains; ++c) {
    TestRng rng(seed + seed_offset(), c);
    Chain<State> chain;
    chain.x = exact_state(f, rng, uint32_t(c));
    chain.fx = f(chain.x);
    std::fill(h.begin(), h.end(), 0.0);
    for (std::size_t t = 0; t < steps; ++t) {
      // one proposal per inner step, as the integrator (a small step draws its refresh)
      const PerturbationProposal prop = PerturbationProposal::make(kind, k_key_seed, 0.1, 0.1, 1, 1, rng);
      stats.record(coherent::inner_step(rule, chain, f, prop, splat, rng, ws));
    }
    for (double& v : h) v /= double(steps);
    splat_means.add(h);
    final_counts[f.bin(chain.x)] += 1.0;
  }
  const char* name = coherent::perturbation_name(kind);
  double stat;
  int dof;
  const double pv = chi_square_p_value(final_counts, probs, &stat, &dof);
  EXPECT_GT(pv, k_alpha) << name << " / " << coherent::inner_rule_name(rule) << ": chi2 = " << stat << ", " << dof
                         << " dof";
  std::size_t worst = 0;
  const double z = splat_means.max_abs_z(probs, &worst);
  EXPECT_LT(z, normal_upper_quantile(k_alpha / (2.0 * double(bins))))
      << name << " splats: bin " << worst << " mean " << splat_means.mean(worst) << " vs " << probs[worst];
  const ChainStats& st = stats[rule == InnerRule::bundle ? MutationKind::bundle : MutationKind::mtm];
  std::printf("[ %-10s %-6s k=%zu ] acceptance %.3f\n", name, coherent::inner_rule_name(rule), tries,
              st.acceptance_rate());
  EXPECT_GT(st.acceptance_rate(), 0.05);  // the chains move (the test has power)
}

TEST(RealProposals, LensPerturbationBundleLeavesTheTargetInvariant) {
  check_real_proposal(Perturbation::lens, InnerRule::bundle, 4, 901);
}

TEST(RealProposals, LensPerturbationMtmLeavesTheTargetInvariant) {
  check_real_proposal(Perturbation::lens, InnerRule::mtm, 4, 902);
}

TEST(RealProposals, PixelMoveBundleLeavesTheTargetInvariant) {
  check_real_proposal(Perturbation::pixel_move, InnerRule::bundle, 2, 903);
}

TEST(RealProposals, SmallStepBundleLeavesTheTargetInvariant) {
  check_real_proposal(Perturbation::small_step, InnerRule::bundle, 4, 904);
}

/// A target that records the kernels' batch-hook calls.
struct PreparedTarget {
  FilmTarget f;
  mutable std::vector<std::size_t> batches;
  mutable std::size_t evaluations = 0, unprepared = 0;
  void prepare(State* states, std::size_t n) const {
    batches.push_back(n);
    for (std::size_t i = 0; i < n; ++i) states[i].evaluated = true;  // "traced"
  }
  double operator()(const State& s) const {
    ++evaluations;
    if (!s.evaluated) ++unprepared;
    return f(s);
  }
};

TEST(RealProposals, EveryBundleIsPreparedOnceBeforeItIsEvaluated) {
  const PreparedTarget target;
  TestRng rng(77);
  const PerturbationProposal prop = PerturbationProposal::make(Perturbation::lens, k_key_seed, 0.1, 0.1, 1, 1, rng);
  const std::size_t k = 5;
  Workspace<State> ws(k, State{});
  auto splat = [](const State&, double) {};
  // f* > 0 everywhere (odd cells 0.25): mtm always has a candidate and draws references
  for (InnerRule rule : {InnerRule::bundle, InnerRule::mtm}) {
    Chain<State> chain;
    chain.x = exact_state(target.f, rng, 1);
    chain.fx = target.f(chain.x);
    target.batches.clear();
    target.evaluations = target.unprepared = 0;
    const StepResult r = coherent::inner_step(rule, chain, target, prop, splat, rng, ws);
    if (rule == InnerRule::bundle) {
      EXPECT_EQ(target.batches, (std::vector<std::size_t>{k}));  // the k candidates
      EXPECT_EQ(r.evaluations, k);
    } else {
      EXPECT_EQ(target.batches, (std::vector<std::size_t>{k, k - 1}));  // candidates, then references
      EXPECT_EQ(r.evaluations, 2 * k - 1);
    }
    EXPECT_EQ(target.evaluations, r.evaluations);
    EXPECT_EQ(target.unprepared, 0u) << "a point was evaluated before prepare()";
  }
}

}  // namespace
}  // namespace cmlt::mcmc
