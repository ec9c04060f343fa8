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
///      bundle by a perturbation (lens / caustic / pixel move), with the rule `inner`:
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
/// Budget: `spp`·W·H path evaluations, bootstrap included (at most half); a bundle step
/// costs k evaluations, an mtm/seed step 2k − 1, the outer step 1.
///
/// Parameters (k, m, σ): study at equal time (tests/bench/cmlt_params.py, 96x96, 2 s per
/// render, 4 seeds interleaved, 2 threads, packets on; relMSE against BDPT 2048 spp,
/// ± its standard error over the seeds; direct pass and pixel importance on):
///     k   m   σ      caustic_glass       cornell
///     2   4   0.01   0.0087 ± 0.0009     0.0075 ± 0.0006
///     2   8   0.01   0.0087 ± 0.0008     0.0077 ± 0.0006
///     4   4   0.01   0.0086 ± 0.0011     0.0097 ± 0.0015
///     4   8   0.01   0.0115 ± 0.0021     0.0081 ± 0.0004
///     8   4   0.01   0.0098 ± 0.0008     0.0139 ± 0.0011
///     8   8   0.01   0.0101 ± 0.0006     0.0092 ± 0.0012
///    16   4   0.01   0.0124 ± 0.0016     0.0165 ± 0.0025
///     4   4   0.03   0.0107 ± 0.0021     0.0067 ± 0.0004
///     4   4   mtm    0.0162 ± 0.0021     0.0233 ± 0.0024   (inner rule mtm)
///   pssmlt           0.0080 ± 0.0007     0.0072 ± 0.0004
///   bdpt             0.0120 ± 0.0029     0.0025 ± 0.0001
/// k = 2, m = 4 is best or tied on both scenes (an earlier caustic run agreed: 0.0082
/// against 0.0100 for k = 8, m = 8), so it is the default (render_settings.h,
/// cmlt/settings.py, the schema). Larger bundles lose at equal time: a step costs k
/// evaluations, and packet tracing saves too little to pay for them (the BVH queries
/// are ~15 % of a bundle's time; tests/bench/packets.py). σ = 0.03 against 0.01 is
/// within the noise (better on cornell, worse on the caustic); σ stays 0.01. (k = 2 was
/// measured with its 2-lane packets traced, 20 % slower than now that fewer than 4
/// pending rays go one by one: bundle_tracer.h's k_min_packet_lanes.)
#include "integrators/common/render_settings.h"

namespace cmlt {

class Scene;

/// Render one frame with coherent MLT. Scene committed, settings validated (render()).
RenderResult render_cmlt(const Scene& scene, const RenderSettings& settings,
                         const ProgressCallback& progress = {});

}  // namespace cmlt
