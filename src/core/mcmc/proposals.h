// cmlt — Metropolis kernels: proposal kernels in primary sample space [0,1)^n.
//
// A Proposal is any type with
//   static constexpr bool k_symmetric;                       // T(x→y) == T(y→x)?
//   template <class State, class Rng>
//   void sample(const State& from, State& to, Rng& rng) const; // write y ~ T(from→·)
// and, only when k_symmetric is false, `double density(const State& from,
// const State& to) const` (used by metropolis_step for the Hastings ratio).
// `to` is pre-sized by the caller (Workspace) and is overwritten, never resized.
// The multiple-try and bundle kernels require a symmetric proposal.
#pragma once

#include <cmath>
#include <cstddef>
#include <iterator>

#include "sampling/rng.h"  // wrap01: the torus of primary sample space

namespace cmlt::mcmc {

/// Small-step mutation: an isotropic Gaussian with standard deviation `sigma` in every
/// coordinate, wrapped onto the torus [0,1)^n.
///
/// The density of `wrap01(x + sigma·N(0, I))` is the wrapped normal
///   K(x, y) = Σ_{m ∈ Z^n} φ_σ(y − x + m),
/// which depends only on (y − x) mod 1 and is even in it, so K(x, y) = K(y, x):
/// the proposal is exactly symmetric on the torus, for any sigma.
struct WrappedGaussianProposal {
  static constexpr bool k_symmetric = true;
  double sigma = 0.05;  ///< per-coordinate standard deviation, > 0 (no upper limit; σ ≳ 1 is ~uniform)

  template <class State, class Rng>
  void sample(const State& from, State& to, Rng& rng) const {
    const std::size_t n = std::size(from);
    for (std::size_t i = 0; i < n; ++i) to[i] = wrap01(from[i] + sigma * rng.normal());
  }
};

/// Large-step mutation: an independent uniform proposal on [0,1)^n. T(x→y) = 1 for all
/// x, y, so it is symmetric and the Metropolis ratio is simply f(y)/f(x).
struct UniformProposal {
  static constexpr bool k_symmetric = true;

  template <class State, class Rng>
  void sample(const State& /*from*/, State& to, Rng& rng) const {
    const std::size_t n = std::size(to);
    for (std::size_t i = 0; i < n; ++i) to[i] = rng.uniform();
  }
};

}  // namespace cmlt::mcmc
