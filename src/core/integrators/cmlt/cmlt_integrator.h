#pragma once
/// \file Coherent Metropolis light transport (integrator "cmlt", DESIGN.md §3).
///
/// Nested chains over primary sample space. The folder: cmlt_state.h (the state: a key
/// plus overrides), perturbations.h (lens, caustic, pixel move, small step),
/// inner_rule.h (which mcmc kernel takes an inner step), cmlt_target.h and
/// bundle_tracer.h (f* of a bundle's candidates, traced in lockstep with packets),
/// cmlt_chain.h (one chain's blocks: the per-thread work), cmlt_settings.h. Per chain,
/// repeated until its budget of path evaluations is spent:
///   1. outer step: a large step (independent uniform point), accepted by
///      Metropolis–Hastings with expected-value splats (mcmc::metropolis_step);
///   2. inner chain: `inner_length` (m) steps of `tries` (k) candidates each, drawn as one
///      bundle by a perturbation (lens / caustic / pixel move / small step), with the
///      rule `inner`:
///      bundle_step (multiple-proposal MH, default), mtm_step (Liu et al., exact) or
///      mtm_step with the seminar's splatting (seed; biased, comparison only).
/// Everything around the chains is shared with PSSMLT (integrators/mlt/: the frame,
/// mlt_frame.h, and the population, chain_population.h): the same bootstrap points (key
/// (bootstrap, i, 1) is PSSMLT's bootstrap sample i, bit for bit), chain starts
/// resampled ∝ f* from the pool (mcmc::resample_start_indices), b from the bootstrap and
/// every outer large step (NormalisationAccumulator), the fixed-point SplatFilm
/// (order-independent: bit-identical over thread counts), MltStats.
///
/// Estimator: every kernel step splats total weight 1, so
///   pixel_j = b · W·H · H_j / (number of steps),  H_j = Σ splats (L/f*)·w in pixel j.
/// Budget: `spp`·W·H path evaluations, the pilot, the direct pass and the bootstrap (at
/// most half of the rest) included (mlt_frame.h); a bundle step costs k evaluations, an
/// mtm/seed step 2k − 1, the outer step 1.
///
/// Defaults of k, m and σ: the equal-time study in tests/bench/results/cmlt_parameters.md.
#include "integrators/common/render_settings.h"

namespace cmlt {

class Scene;

/// Render one frame with coherent MLT. Scene committed, settings validated (render()).
RenderResult render_cmlt(const Scene& scene, const RenderSettings& settings,
                         const ProgressCallback& progress = {});

}  // namespace cmlt
