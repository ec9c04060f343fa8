// cmlt — Metropolis kernels (umbrella header).
//
// Generic, exact Metropolis building blocks for the PSSMLT and coherent-MLT integrators,
// independent of rendering (DESIGN.md §2–§3):
//   metropolis_step / large_step   single proposal, expected-value splatting
//   mtm_step (MtmSplatRule::mtm)   multiple-try Metropolis, exact splatting
//   mtm_step (MtmSplatRule::seed)  the seminar's 2k splatting rule (biased; comparison only)
//   bundle_step                    multiple-proposal MH on a coherent bundle (default)
//   bootstrap / resample_start_*   normalisation b = E[f*] and unbiased chain starts
// Tests: tests/cpp/mcmc/.
#pragma once

#include "kernels.h"
#include "normalisation.h"
#include "proposals.h"
#include "rng.h"
#include "step_stats.h"
#include "workspace.h"
