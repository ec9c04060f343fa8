// Tests of the MCMC kernels: chain starts for toy targets — a chain started at a given
// point, a bootstrap pool of uniform points and chains resampled from it. The renderer
// does the same through its own code (integrators/mlt/chain_population.h); these are
// the small generic forms the toy tests need.
#pragma once

#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "mcmc/mcmc.h"

namespace cmlt::mcmc::testing {

/// Start a chain at `x`, evaluating the target once. A negative, NaN or infinite value
/// is stored as 0 (such a chain leaves at its first proposal with f* > 0).
template <class State, class Target>
Chain<State> make_chain(State x, const Target& f) {
  Chain<State> c{std::move(x), 0.0};
  const double v = static_cast<double>(f(c.x));
  c.fx = (v >= 0.0 && std::isfinite(v)) ? v : 0.0;
  return c;
}

/// The bootstrap: N independent uniform states, their f* values and the estimate of b.
template <class State>
struct BootstrapPool {
  std::vector<State> states;
  std::vector<double> values;  ///< f*(states[i]), sanitised (invalid → 0)
  NormalisationEstimate b;
};

/// Draw `n` independent states with `draw` (default: uniform on [0,1)^dim, the size of
/// `prototype`), evaluate f* once each, and estimate b. Allocates (not an inner step).
template <class State, class Target, class Rng, class Draw = UniformProposal>
BootstrapPool<State> bootstrap(const Target& f, std::size_t n, const State& prototype, Rng& rng,
                               const Draw& draw = Draw{}) {
  BootstrapPool<State> pool;
  pool.states.assign(n, prototype);
  pool.values.assign(n, 0.0);
  NormalisationAccumulator acc;
  for (std::size_t i = 0; i < n; ++i) {
    draw.sample(prototype, pool.states[i], rng);
    const double v = static_cast<double>(f(pool.states[i]));
    pool.values[i] = (v >= 0.0 && std::isfinite(v)) ? v : 0.0;
    acc.add(pool.values[i]);
  }
  pool.b = acc.estimate();
  return pool;
}

/// Resample `n` chain start states from `pool` ∝ `weights` (normally the pool's f*).
template <class State, class Rng>
std::vector<State> resample_start_states(const std::vector<State>& pool, const std::vector<double>& weights,
                                         std::size_t n, Rng& rng) {
  if (pool.size() != weights.size())
    throw std::invalid_argument("mcmc::resample_start_states: pool has " + std::to_string(pool.size()) +
                                " states but " + std::to_string(weights.size()) + " weights");
  std::vector<State> out;
  out.reserve(n);
  for (std::size_t i : resample_start_indices(weights, n, rng)) out.push_back(pool[i]);
  return out;
}

/// Start `n` chains from a bootstrap pool (resampled ∝ f*), reusing the pool's f* values.
template <class State, class Rng>
std::vector<Chain<State>> start_chains(const BootstrapPool<State>& pool, std::size_t n, Rng& rng) {
  std::vector<Chain<State>> chains;
  chains.reserve(n);
  for (std::size_t i : resample_start_indices(pool.values, n, rng))
    chains.push_back(Chain<State>{pool.states[i], pool.values[i]});
  return chains;
}

}  // namespace cmlt::mcmc::testing
