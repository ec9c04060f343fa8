// cmlt — Metropolis kernels: chain state and the reusable scratch of a step.
#pragma once

#include <cmath>
#include <cstddef>
#include <stdexcept>
#include <utility>
#include <vector>

namespace cmlt::mcmc {

/// A Markov chain: its current state and the target value there. The kernels evaluate
/// the target once per new point and carry f*(x) along, so a State that caches its
/// path colour (filled in by the target) keeps it in step with fx.
template <class State>
struct Chain {
  State x{};
  double fx = 0.0;  ///< f*(x); > 0 for a properly started chain
};

/// Scratch for one chain (one per thread): every buffer is sized at construction, so a
/// step performs no heap allocation — states are overwritten element-wise (same size,
/// so std::vector assignment reuses capacity) or swapped with the chain's state.
template <class State>
struct Workspace {
  /// `tries` = k, the candidates per multiple-try or bundle step (≥ 1); `prototype`
  /// fixes the size of every scratch state (its values are irrelevant).
  Workspace(std::size_t tries, const State& prototype)
      : y(tries, prototype), z(tries, prototype), fy(tries, 0.0), fz(tries, 0.0), centre(prototype) {
    if (tries == 0) throw std::invalid_argument("mcmc::Workspace: tries (k) must be at least 1");
  }

  std::size_t tries() const { return y.size(); }

  std::vector<State> y;    ///< candidates y_1..y_k (metropolis_step uses y[0])
  std::vector<State> z;    ///< MTM reference points z_1..z_{k-1} (z_k = x is not copied)
  std::vector<double> fy;  ///< f*(y_l)
  std::vector<double> fz;  ///< f*(z_l)
  State centre;            ///< bundle centre c
};

}  // namespace cmlt::mcmc
