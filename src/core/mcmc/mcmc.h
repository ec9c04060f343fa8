// cmlt — generic Markov-chain Monte Carlo kernels (umbrella header), namespace cmlt::mcmc.
//
// Exact Metropolis building blocks, independent of rendering (DESIGN.md §2–§3), used by
// the PSSMLT and coherent-MLT integrators (integrators/pssmlt, integrators/cmlt):
//   metropolis_step / large_step   single proposal, expected-value splatting
//   mtm_step (MtmSplatRule::mtm)   multiple-try Metropolis, exact splatting
//   mtm_step (MtmSplatRule::seed)  the seminar's 2k splatting rule (biased; comparison only)
//   bundle_step                    multiple-proposal MH on a coherent bundle
//   NormalisationAccumulator,      normalisation b = E[f*] and unbiased chain starts
//   resample_start_indices
//   Chain, Workspace, StepResult,  chain state, scratch, per-step and per-kind statistics
//   KernelStats
//   StreakTracker, ChainShare,     how long chains stay put, how their splat weight spreads
//   ShareSummary
// The kernels are templates over the chain state, the target, the proposal and the RNG
// (`uniform()`, `normal()`); the renderer passes sampling/rng.h's CounterRng. Tests with
// toy targets: tests/cpp/mcmc/.
#pragma once

#include "chain_diagnostics.h"
#include "kernels.h"
#include "normalisation.h"
#include "proposals.h"
#include "step_stats.h"
#include "workspace.h"
