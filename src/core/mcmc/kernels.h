// cmlt — Metropolis kernels: one step of each Markov-chain rule, with expected-value
// splatting. Generic over
//   State    the chain state (e.g. primary samples + technique); copyable, swappable;
//   Target   callable `double f(const State&)`: the unnormalised target f* ≥ 0
//            (NaN, ±Inf and negative values are counted as invalid and treated as 0);
//   Proposal see proposals.h (symmetric for mtm_step and bundle_step);
//   Splat    callable `void splat(const State&, double weight)`, called only with
//            weight > 0; the weights of one step sum to 1;
//   Rng      `double uniform()` in [0,1), `double normal()`.
// The MLT estimate of ∫ h_j f* is then  b · (Σ of weights splatted into j) / steps,
// with b = ∫ f* (see normalisation.h); a renderer splat adds b·colour/f* × weight.
//
// A point with f* = 0 is never accepted and never gets a positive splat weight, except
// the chain's own state when a chain was (wrongly) started where f* = 0: then the step
// keeps the weights summing to 1 by splatting x, and the renderer's splat must treat
// colour/f* = 0/0 as zero. Start chains by resampling a bootstrap pool
// (resample_start_indices, normalisation.h).
//
// Determinism: each step's random numbers depend only on the RNG state and on the
// target values, so a given seed replays the chain bit for bit. No heap allocation:
// all scratch lives in a pre-sized Workspace.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <utility>

#include "proposals.h"
#include "step_stats.h"
#include "workspace.h"

namespace cmlt::mcmc {

/// Splatting rule of the multiple-try step.
enum class MtmSplatRule : std::uint8_t {
  mtm,   ///< y* with a, x with 1−a: the expected value of the next state (exact)
  seed,  ///< the seminar's rule: every y_l with a·f*(y_l)/F_y and every z_l with
         ///< (1−a)·f*(z_l)/F_z. Biased (see tests/cpp/mcmc/test_seed_rule.cpp):
         ///< the z_l lie around y*, not x. Kept for comparison only.
};

namespace detail {

/// Evaluate the target once, sanitising its value: NaN, ±Inf and negatives → 0.
template <class Target, class State>
inline double evaluate(const Target& f, const State& s, StepResult& r) {
  const double v = static_cast<double>(f(s));
  ++r.evaluations;
  if (!(v >= 0.0) || !std::isfinite(v)) {  // `!(v >= 0)` is also true for NaN
    ++r.invalid_values;
    ++r.zero_values;
    return 0.0;
  }
  if (v == 0.0) ++r.zero_values;
  return v;
}

/// Splat with a positive weight only.
template <class Splat, class State>
inline void emit(Splat& splat, const State& s, double weight, StepResult& r) {
  if (weight > 0.0) {
    splat(s, weight);
    ++r.splats;
    r.splatted_weight += weight;
  }
}

/// Index i of the first positive weight whose cumulative sum exceeds t (0 ≤ t < Σw).
/// Never returns an index with zero weight; if rounding leaves t ≥ the running sum at
/// the end, returns the last positive weight; returns n only when no weight is positive.
inline std::size_t select_by_target(const double* w, std::size_t n, double t) {
  double cumulative = 0.0;
  std::size_t last_positive = n;
  for (std::size_t i = 0; i < n; ++i) {
    if (w[i] > 0.0) {
      cumulative += w[i];
      last_positive = i;
      if (t < cumulative) return i;
    }
  }
  return last_positive;
}

inline double min1(double v) { return v < 1.0 ? v : 1.0; }

/// Optional batch hook: a Target with a member `void prepare(State* states, std::size_t n)
/// const` is called once with all the points of a bundle (mtm_step's candidates, its
/// reference points, bundle_step's candidates) after they are drawn and before any is
/// evaluated, so a renderer can trace their first rays together (Embree packets). The
/// kernels draw every point of a bundle before evaluating any; the target never reads
/// the kernel RNG, so the random stream and every result are the same with or without
/// a prepare hook.
template <class Target, class State, class = void>
struct has_prepare : std::false_type {};
template <class Target, class State>
struct has_prepare<Target, State,
                   std::void_t<decltype(std::declval<const Target&>().prepare(std::declval<State*>(),
                                                                              std::size_t{}))>>
    : std::true_type {};

template <class Target, class State>
inline void prepare(const Target& f, State* states, std::size_t n) {
  if constexpr (has_prepare<Target, State>::value) f.prepare(states, n);
}

/// One bundle: draw out[0..n) ~ T(from→·), hand them to the batch hook, then evaluate
/// each into values[0..n). Returns `sum` plus the values, added in order.
template <class State, class Target, class Proposal, class Rng>
inline double draw_bundle(const Target& f, const Proposal& proposal, const State& from, State* out, double* values,
                          std::size_t n, Rng& rng, double sum, StepResult& r) {
  for (std::size_t l = 0; l < n; ++l) proposal.sample(from, out[l], rng);
  if (n > 0) prepare(f, out, n);
  for (std::size_t l = 0; l < n; ++l) {
    values[l] = evaluate(f, out[l], r);
    sum += values[l];
  }
  return sum;
}

/// The chain moves to `to` (point `index` + 1 of the step: 0 is x), whose value is `fy`.
template <class State>
inline void move_to(Chain<State>& chain, State& to, double fy, std::size_t index, StepResult& r) {
  using std::swap;
  swap(chain.x, to);
  chain.fx = fy;
  r.moved = true;
  r.chosen = static_cast<std::uint32_t>(index + 1);
}

}  // namespace detail

/// The two halves of metropolis_step (below), for a caller that evaluates many chains' proposals
/// together between them (coherent MLT's chains in lockstep): draw y into ws.y[0] ...
template <class State, class Proposal, class Rng>
void metropolis_draw(const Chain<State>& chain, const Proposal& proposal, Rng& rng, Workspace<State>& ws) {
  proposal.sample(chain.x, ws.y[0], rng);
}

/// ... then evaluate it (the target's cached value, if the caller evaluated it) and
/// finish the step. The same numbers in the same order as metropolis_step.
template <class State, class Target, class Proposal, class Splat, class Rng>
StepResult metropolis_finish(Chain<State>& chain, const Target& f, const Proposal& proposal, Splat&& splat,
                             Rng& rng, Workspace<State>& ws, MutationKind kind = MutationKind::small_step) {
  StepResult r;
  r.kind = kind;
  State& y = ws.y[0];
  const double fy = detail::evaluate(f, y, r);

  // acceptance probability, without 0/0
  double a = 0.0;
  if (fy > 0.0) {
    if constexpr (Proposal::k_symmetric) {
      a = chain.fx > 0.0 ? detail::min1(fy / chain.fx) : 1.0;
    } else {
      const double num = fy * proposal.density(y, chain.x);
      const double den = chain.fx * proposal.density(chain.x, y);
      a = den > 0.0 ? detail::min1(num / den) : (num > 0.0 ? 1.0 : 0.0);
      if (!(a >= 0.0)) a = 0.0;  // NaN guard for a non-finite density
    }
  }
  r.acceptance = a;

  // expected-value splatting: proposed state a, current state 1−a
  detail::emit(splat, y, a, r);
  detail::emit(splat, chain.x, 1.0 - a, r);

  // accept or reject; on reject chain.x is untouched (bit-exact)
  if (rng.uniform() < a) detail::move_to(chain, y, fy, 0, r);
  return r;
}

/// One Metropolis–Hastings step with a single proposal y ~ T(x→·) and expected-value
/// splatting (Veach 1997 §11.5; Kelemen et al. 2002): y gets weight a, x gets 1−a, with
/// a = min(1, f*(y) T(y→x) / (f*(x) T(x→y))) — for a symmetric T simply f*(y)/f*(x).
/// A proposal with f*(y) = 0 has a = 0 (no 0/0 is ever formed).
template <class State, class Target, class Proposal, class Splat, class Rng>
StepResult metropolis_step(Chain<State>& chain, const Target& f, const Proposal& proposal, Splat&& splat,
                           Rng& rng, Workspace<State>& ws,
                           MutationKind kind = MutationKind::small_step) {
  metropolis_draw(chain, proposal, rng, ws);
  return metropolis_finish(chain, f, proposal, splat, rng, ws, kind);
}

/// Large step: metropolis_step with the independent uniform proposal (T ≡ 1), so the
/// acceptance is min(1, f*(y)/f*(x)).
template <class State, class Target, class Splat, class Rng>
StepResult large_step(Chain<State>& chain, const Target& f, Splat&& splat, Rng& rng, Workspace<State>& ws) {
  return metropolis_step(chain, f, UniformProposal{}, splat, rng, ws, MutationKind::large_step);
}

/// One multiple-try Metropolis step (Liu, Liang & Wong 2000, JASA 95(449), §2) with
/// k = ws.tries() candidates and weights w(x, y) = f*(y) (symmetric T, λ = 1/T):
///  1. draw y_1..y_k ~ T(x→·);
///  2. pick y* = y_j with probability f*(y_j) / F_y, F_y = Σ f*(y_l);
///  3. draw z_1..z_{k−1} ~ T(y*→·) and set z_k = x;
///  4. accept y* with a = min(1, F_y / F_z), F_z = Σ f*(z_l).
/// Splatting by `rule` (see MtmSplatRule). If every candidate has f* = 0, y* is
/// undefined and a = 0: x is splatted with weight 1 under both rules.
/// Cost: 2k − 1 target evaluations.
template <class State, class Target, class Proposal, class Splat, class Rng>
StepResult mtm_step(Chain<State>& chain, const Target& f, const Proposal& proposal, Splat&& splat, Rng& rng,
                    Workspace<State>& ws, MtmSplatRule rule = MtmSplatRule::mtm) {
  static_assert(Proposal::k_symmetric, "mtm_step uses w(x,y) = f*(y), which needs a symmetric proposal");
  StepResult r;
  r.kind = rule == MtmSplatRule::mtm ? MutationKind::mtm : MutationKind::seed;
  const std::size_t k = ws.tries();

  // 1. draw and evaluate the k candidates (one coherent bundle in the renderer)
  const double fy_sum = detail::draw_bundle(f, proposal, chain.x, ws.y.data(), ws.fy.data(), k, rng, 0.0, r);
  if (!(fy_sum > 0.0)) {  // no candidate can be chosen: stay
    r.acceptance = 0.0;
    detail::emit(splat, chain.x, 1.0, r);
    return r;
  }

  // 2. pick y* by weight
  const std::size_t j = detail::select_by_target(ws.fy.data(), k, rng.uniform() * fy_sum);
  const State& y_star = ws.y[j];

  // 3. reference points around y*; z_k = x enters through chain.fx (not copied)
  const double fz_sum = detail::draw_bundle(f, proposal, y_star, ws.z.data(), ws.fz.data(), k - 1, rng, chain.fx, r);

  // 4. generalised Metropolis ratio; F_z ≥ f*(x) > 0 for a started chain
  const double a = fz_sum > 0.0 ? detail::min1(fy_sum / fz_sum) : 1.0;
  r.acceptance = a;

  // 5. splat
  if (rule == MtmSplatRule::mtm) {
    detail::emit(splat, y_star, a, r);
    detail::emit(splat, chain.x, 1.0 - a, r);
  } else {
    for (std::size_t l = 0; l < k; ++l) detail::emit(splat, ws.y[l], a * (ws.fy[l] / fy_sum), r);
    if (fz_sum > 0.0) {
      const double rest = 1.0 - a;
      for (std::size_t l = 0; l + 1 < k; ++l) detail::emit(splat, ws.z[l], rest * (ws.fz[l] / fz_sum), r);
      detail::emit(splat, chain.x, rest * (chain.fx / fz_sum), r);
    }
  }

  // 6. accept or reject
  if (rng.uniform() < a) detail::move_to(chain, ws.y[j], ws.fy[j], j, r);
  return r;
}

/// The two halves of bundle_step (below), for a caller that evaluates many chains' bundles together
/// between them (coherent MLT's chains in lockstep): draw the centre around x and the k
/// candidates around it into ws ...
template <class State, class Proposal, class Rng>
void bundle_draw(const Chain<State>& chain, const Proposal& proposal, Rng& rng, Workspace<State>& ws) {
  static_assert(Proposal::k_symmetric, "bundle_step needs a symmetric kernel for exchangeability");
  proposal.sample(chain.x, ws.centre, rng);
  for (std::size_t l = 0; l < ws.tries(); ++l) proposal.sample(ws.centre, ws.y[l], rng);
}

/// ... then evaluate the candidates (the target's cached values, if the caller evaluated
/// them), splat and draw the next state. The same numbers in the same order as
/// bundle_step.
template <class State, class Target, class Splat, class Rng>
StepResult bundle_finish(Chain<State>& chain, const Target& f, Splat&& splat, Rng& rng, Workspace<State>& ws) {
  StepResult r;
  r.kind = MutationKind::bundle;
  const std::size_t k = ws.tries();
  double fy_sum = 0.0;
  for (std::size_t l = 0; l < k; ++l) {
    ws.fy[l] = detail::evaluate(f, ws.y[l], r);
    fy_sum += ws.fy[l];
  }
  const double total = chain.fx + fy_sum;
  if (!(total > 0.0)) {
    r.acceptance = 0.0;
    detail::emit(splat, chain.x, 1.0, r);
    return r;
  }
  r.acceptance = fy_sum / total;

  // splat all k+1 points by their share of S
  detail::emit(splat, chain.x, chain.fx / total, r);
  for (std::size_t l = 0; l < k; ++l) detail::emit(splat, ws.y[l], ws.fy[l] / total, r);

  // draw the next state from {x, y_1..y_k} ∝ f*
  const double t = rng.uniform() * total;
  if (t < chain.fx || !(fy_sum > 0.0)) return r;  // stay at x
  const std::size_t j = detail::select_by_target(ws.fy.data(), k, t - chain.fx);
  detail::move_to(chain, ws.y[j], ws.fy[j], j, r);
  return r;
}

/// One multiple-proposal Metropolis–Hastings step on a coherent bundle (Tjelmeland 2004,
/// "Using all Metropolis–Hastings proposals to estimate mean values", §2; Calderhead 2014,
/// PNAS 111(49)): draw a centre c ~ T(x→·), then k = ws.tries() candidates
/// y_l ~ T(c→·); the next state is drawn from {x, y_1..y_k} with probability
/// f*(p)/S, S = f*(x) + Σ f*(y_l), and every point is splatted with f*(p)/S (the
/// expected value of the next state). If S = 0, stay and splat x with weight 1.
/// Cost: k target evaluations (the centre is not evaluated).
///
/// Why this is exact, also on the torus. With the wrapped kernel K(a, b) = K(b, a)
/// (proposals.h), the joint proposal density of the bundle given any one member p_i is
///   G(p_0, …, p_k) = ∫ K(c, p_0) K(c, p_1) ⋯ K(c, p_k) dc,
/// where we used K(p_0, c) = K(c, p_0) for the first level. G is symmetric under every
/// permutation of (p_0, …, p_k): x = p_0 and the y_l are exchangeable. So the extended
/// target π(p_i)·G(p_0..p_k) on (set, index i) has the index's conditional ∝ f*(p_i),
/// drawing the index from it is a Gibbs step, and π stays invariant. Wrapping changes
/// nothing as long as the *same* wrapped kernel is used for both levels: with different
/// widths, K1(c, x) ∏ K2(c, y_l) is no longer symmetric in x and the y_l.
template <class State, class Target, class Proposal, class Splat, class Rng>
StepResult bundle_step(Chain<State>& chain, const Target& f, const Proposal& proposal, Splat&& splat, Rng& rng,
                       Workspace<State>& ws) {
  static_assert(Proposal::k_symmetric, "bundle_step needs a symmetric kernel for exchangeability");
  bundle_draw(chain, proposal, rng, ws);
  detail::prepare(f, ws.y.data(), ws.tries());
  return bundle_finish(chain, f, splat, rng, ws);
}

}  // namespace cmlt::mcmc
