// The kernels under test, as one enumeration, so every statistical test runs over all of them.
#pragma once

#include <string>

#include "toy_targets.h"

namespace cmlt::mcmc::testing {

enum class Kernel { small_step, large_step, pssmlt_mixture, mtm, seed, bundle };

inline const char* kernel_name(Kernel k) {
  switch (k) {
    case Kernel::small_step: return "small_step";
    case Kernel::large_step: return "large_step";
    case Kernel::pssmlt_mixture: return "pssmlt_mixture";
    case Kernel::mtm: return "mtm";
    case Kernel::seed: return "seed";
    case Kernel::bundle: return "bundle";
  }
  return "?";
}

struct KernelParams {
  Kernel kernel = Kernel::mtm;
  std::size_t tries = 8;             ///< k for mtm / seed / bundle
  double sigma = 0.1;                ///< wrapped Gaussian width
  double large_step_probability = 0.25;  ///< for pssmlt_mixture
};

inline std::string case_name(const KernelParams& p) {
  std::string s = kernel_name(p.kernel);
  if (p.kernel == Kernel::mtm || p.kernel == Kernel::seed || p.kernel == Kernel::bundle)
    s += "_k" + std::to_string(p.tries);
  if (p.kernel != Kernel::large_step) s += "_s" + std::to_string(int(p.sigma * 1000 + 0.5));
  return s;
}

/// One step of the chosen kernel.
template <class State, class Target, class Splat, class Rng>
StepResult do_step(const KernelParams& p, Chain<State>& chain, const Target& f, Splat& splat, Rng& rng,
                   Workspace<State>& ws) {
  const WrappedGaussianProposal T{p.sigma};
  switch (p.kernel) {
    case Kernel::small_step: return metropolis_step(chain, f, T, splat, rng, ws);
    case Kernel::large_step: return large_step(chain, f, splat, rng, ws);
    case Kernel::pssmlt_mixture:
      // the choice uses its own uniform before the step: a mixture of π-invariant kernels
      if (rng.uniform() < p.large_step_probability) return large_step(chain, f, splat, rng, ws);
      return metropolis_step(chain, f, T, splat, rng, ws);
    case Kernel::mtm: return mtm_step(chain, f, T, splat, rng, ws, MtmSplatRule::mtm);
    case Kernel::seed: return mtm_step(chain, f, T, splat, rng, ws, MtmSplatRule::seed);
    case Kernel::bundle: return bundle_step(chain, f, T, splat, rng, ws);
  }
  return {};
}

/// Many independent short chains, each started from an exact draw of π.
struct ShortChainResult {
  std::vector<double> final_counts;  ///< histogram of the chains' final states
  BinMeans splat_means;              ///< per chain: splatted weight per bin / steps
  KernelStats stats;
  double max_weight_error = 0;       ///< max over steps of |Σ splat weights − 1|
  std::size_t nonfinite_splats = 0;
  explicit ShortChainResult(std::size_t bins) : final_counts(bins, 0.0), splat_means(bins) {}
};

template <class Target, class StepFn>
ShortChainResult run_short_chains(const Binned<Target>& bn, std::size_t chains, std::size_t steps,
                                  std::uint64_t seed, std::size_t tries, StepFn&& step) {
  ShortChainResult out(bn.bins());
  Workspace<Vec> ws(tries, Vec(Target::k_dims, 0.0));
  std::vector<double> h(bn.bins());
  auto splat = [&](const Vec& u, double w) {
    if (!std::isfinite(w)) ++out.nonfinite_splats;
    h[bn.bin(u)] += w;
  };
  for (std::size_t c = 0; c < chains; ++c) {
    TestRng rng(seed + seed_offset(), c);
    auto chain = make_chain(bn.exact_draw(rng), bn.target);
    std::fill(h.begin(), h.end(), 0.0);
    for (std::size_t t = 0; t < steps; ++t) {
      const StepResult r = step(chain, splat, rng, ws);
      out.stats.record(r);
      out.max_weight_error = std::max(out.max_weight_error, std::abs(r.splatted_weight - 1.0));
    }
    for (double& v : h) v /= double(steps);
    out.splat_means.add(h);
    out.final_counts[bn.bin(chain.x)] += 1.0;
  }
  return out;
}

template <class Target>
ShortChainResult run_short_chains(const Binned<Target>& bn, const KernelParams& p, std::size_t chains,
                                  std::size_t steps, std::uint64_t seed) {
  return run_short_chains(bn, chains, steps, seed, p.tries, [&](auto& chain, auto& splat, auto& rng, auto& ws) {
    return do_step(p, chain, bn.target, splat, rng, ws);
  });
}

}  // namespace cmlt::mcmc::testing
