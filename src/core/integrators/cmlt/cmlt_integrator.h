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
/// Parameters (σ, k, m): study on sequences/cornell, 96x96, 2 s per render, 3 seeds,
/// relMSE against the 2048-spp BDPT reference (tests/bench/cmlt_params.py, 2 threads on
/// a shared, loaded machine):
///     σ      k   m   evals/px  relMSE        σ      k   m   evals/px  relMSE
///     0.01   8   8   154       0.0147        0.01   4   8   108       0.0167
///     0.003  8   8   175       0.0536        0.01  16   8   138       0.0239
///     0.03   8   8   121       0.0116        0.01   8   2   286       0.0076
///     0.1    8   8   121       0.0125        0.01   8  32   139       0.0159
///     0.03   8   2   101       0.0182        0.01   8   1   161       0.0141
///     0.01   4   2    92       0.0188
/// σ = 0.003 (0.3 px) is clearly too small; σ ∈ [0.01, 0.1] and m are within the noise of
/// the time calibration (the evaluations that fit 2 s varied 2–3× between runs of the same
/// configuration under the machine's load: compare m = 2 at 286 vs 101 evals/px), k = 16
/// is worse than k = 8. Inconclusive beyond that, so the defaults stay σ = 0.01, k = 8,
/// m = 8 (render_settings.h, cmlt/settings.py); redo at equal evaluations on an idle machine.
#include "integrators/common/render_settings.h"

namespace cmlt {

class Scene;

/// Render one frame with coherent MLT. Scene committed, settings validated (render()).
RenderResult render_cmlt(const Scene& scene, const RenderSettings& settings,
                         const ProgressCallback& progress = {});

}  // namespace cmlt
