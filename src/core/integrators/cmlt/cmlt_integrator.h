#pragma once
/// \file Coherent Metropolis light transport (integrator "cmlt", DESIGN.md §3).
///
/// Nested chains over primary sample space (cmlt_state.h for the state, perturbations
/// and coherent tracing). Per chain, repeated until its budget of path evaluations is
/// spent:
///   1. outer step: a large step (independent uniform point), accepted by
///      Metropolis–Hastings with expected-value splats (mlt_kernels' metropolis_step);
///   2. inner chain: `inner_length` (m) steps of `tries` (k) candidates each, drawn as one
///      bundle by a perturbation (lens / caustic / pixel move), with the rule `inner`:
///      bundle_step (multiple-proposal MH, default), mtm_step (Liu et al., exact) or
///      mtm_step with the seminar's splatting (seed; biased, comparison only).
/// Everything around the chains is PSSMLT's (pssmlt_integrator.h): the same bootstrap
/// points (key (bootstrap, i, 1) is PSSMLT's bootstrap sample i, bit for bit), chain
/// starts resampled ∝ f* from the pool (mlt_kernels' resample_start_indices), b from the
/// bootstrap and every outer large step (NormalisationAccumulator), the fixed-point
/// SplatFilm (order-independent: bit-identical over thread counts), MltStats.
///
/// Estimator: every kernel step splats total weight 1, so
///   pixel_j = b · W·H · H_j / (number of steps),  H_j = Σ splats (L/f*)·w in pixel j.
/// Budget: `spp`·W·H path evaluations, bootstrap included (at most half); a bundle step
/// costs k evaluations, an mtm/seed step 2k − 1, the outer step 1.
///
/// Parameters (σ, k, m): parameter study on sequences/cornell (96x96, equal time, relMSE
/// against a 2048-spp BDPT reference; tests/bench/cmlt_params.py) — see the report in the
/// commit log and the defaults in render_settings.h.
#include "integrators/common/render_settings.h"

namespace cmlt {

class Scene;

/// Render one frame with coherent MLT. Scene committed, settings validated (render()).
RenderResult render_cmlt(const Scene& scene, const RenderSettings& settings,
                         const ProgressCallback& progress = {});

}  // namespace cmlt
