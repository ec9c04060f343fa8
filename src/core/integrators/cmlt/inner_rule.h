#pragma once
/// \file The inner-chain rule of coherent MLT (DESIGN.md §3; RenderSettings::inner):
/// which kernel of src/core/mcmc takes an inner step on a bundle of `tries` candidates.
///   bundle  multiple-proposal MH (Tjelmeland 2004; mcmc::bundle_step), exact: every
///           one of the k + 1 points is splatted; k evaluations a step (the default);
///   mtm     multiple-try Metropolis (Liu et al. 2000; mcmc::mtm_step), exact; 2k − 1
///           evaluations a step;
///   seed    mtm_step with the seminar's 2k splats (MtmSplatRule::seed): biased, kept for
///           comparison only (tests/cpp/mcmc/test_seed_rule.cpp measures the bias).
/// The default is the exact rule with the lowest error per step and per traced path on
/// the toy targets (tests/cpp/mcmc) and at equal time on the example scenes
/// (tests/bench/results/cmlt_parameters.md).
#include "mcmc/kernels.h"

#include <cstdint>
#include <string>

namespace cmlt::coherent {

enum class InnerRule : std::uint8_t { seed, mtm, bundle };

inline constexpr InnerRule k_default_inner_rule = InnerRule::bundle;

inline const char* inner_rule_name(InnerRule rule) {
    switch (rule) {
        case InnerRule::seed: return "seed";
        case InnerRule::mtm: return "mtm";
        case InnerRule::bundle: return "bundle";
    }
    return "unknown";
}

/// The rule a settings name spells ("seed", "mtm"; anything else — validated before —
/// "bundle").
inline InnerRule parse_inner_rule(const std::string& name) {
    if (name == "seed") return InnerRule::seed;
    if (name == "mtm") return InnerRule::mtm;
    return InnerRule::bundle;
}

/// One inner-chain step with the chosen rule (the kernels' template arguments).
template <class State, class Target, class Proposal, class Splat, class Rng>
mcmc::StepResult inner_step(InnerRule rule, mcmc::Chain<State>& chain, const Target& f, const Proposal& proposal,
                            Splat&& splat, Rng& rng, mcmc::Workspace<State>& ws) {
    switch (rule) {
        case InnerRule::seed: return mcmc::mtm_step(chain, f, proposal, splat, rng, ws, mcmc::MtmSplatRule::seed);
        case InnerRule::mtm: return mcmc::mtm_step(chain, f, proposal, splat, rng, ws, mcmc::MtmSplatRule::mtm);
        case InnerRule::bundle: break;
    }
    return mcmc::bundle_step(chain, f, proposal, splat, rng, ws);
}

}  // namespace cmlt::coherent
