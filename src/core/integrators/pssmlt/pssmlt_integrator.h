#pragma once
/// \file Primary-sample-space Metropolis light transport (Kelemen et al. 2002) — the
/// frame loop: bootstrap, chain starts, chains in parallel, normalisation, image (the
/// population shared with cmlt: integrators/mlt/chain_population.h; one chain and its
/// steps: pssmlt_chain.h). The path sampler (integrators/mlt/pssmlt_tracer.h) is multiplexed BDPT by default (Hachisuka et al. 2014:
/// the technique — depth, (s, t) — is part of the state, drawn from its own primary
/// samples, held fixed by small steps and redrawn by large steps; technique.h) or the
/// path tracer (RenderSettings::mlt_path_sampler = "pt").
///
/// Depth handling: the depth is part of the state with a fixed pmf (technique.h), not
/// pbrt's per-depth bootstrap with chains pinned to a depth: resampling the bootstrap
/// pool ∝ f* already distributes the chains over depths ∝ b_depth, and large steps
/// let every chain move between depths, so a chain's time per depth converges to
/// b_depth / b instead of being fixed by the (multinomial) start.
///
/// Chain states: RenderSettings::mlt_initial_states replaces step 2 (chains start from
/// the given states, re-evaluated in this frame's scene; the bootstrap still gives b);
/// RenderResult::mlt_states returns every chain's final state, mlt_start_states the states
/// they started from (chain_state.h; the temporal driver carries a mix of both).
///
/// Estimator (Veach 1997 §11.3; DESIGN.md §2). With f*(u) = luminance(L(u)) / P(pixel)
/// over primary samples u ∈ [0,1)^∞ (P: the pixel importance, pixel_importance.h; 1 for
/// the luminance target) and b = ∫ f*(u) du:
///   pixel_j = W·H · ∫ h_j(u) L(u) du ≈ b · H_j / (M / (W·H)),
///   H_j = Σ over the M mutations of the expected-value splats (L/f*)·w in pixel j
/// (proposal weight a, current state 1−a: mcmc::metropolis_step).
///   0. the pilot of the pixel importance and, interleaved with the chain rounds, the
///      direct pass (depths 0 and 1 path traced, added to the image; the chains then
///      render depth >= 2): integrators/mlt/mlt_frame.h, direct_pass.h;
///   1. bootstrap: N independent large-step samples (parallel, deterministic), b̂ = mean f*;
///   2. chains start by resampling the bootstrap pool ∝ f* (no start-up bias,
///      mcmc/normalisation.h), replaying the chosen sample from its key;
///   3. each chain takes its share of the M mutations left of spp·W·H after the pilot,
///      the direct pass and the bootstrap (or runs to the time budget, frame_loop.h): a
///      large step with probability `large_step_probability`, else a small
///      wrapped-Gaussian step σ;
///   4. the f* of every large-step proposal is an independent sample of b too: b is the
///      mean over the bootstrap and all large steps (NormalisationAccumulator, merged in
///      chain order).
/// The chain count is a setting (default 1000), never the thread count: chain c's
/// numbers are keyed by (seed, c) and splats are summed order-independently, so the
/// image is bit-identical for any number of threads.
#include "integrators/common/render_settings.h"

namespace cmlt {

class Scene;

/// Render one frame with PSSMLT (integrator "pssmlt"). The scene must be committed and
/// the settings validated (render() does both). `progress(done, total)` is called on
/// the calling thread after each chain round, in units of `spp` (path evaluations per
/// pixel; milliseconds with a time budget, frame_loop.h); returning false stops the
/// chains and the image is normalised by the mutations taken.
RenderResult render_pssmlt(const Scene& scene, const RenderSettings& settings,
                           const ProgressCallback& progress = {});

}  // namespace cmlt
