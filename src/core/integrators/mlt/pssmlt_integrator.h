#pragma once
/// \file Primary-sample-space Metropolis light transport (Kelemen et al. 2002) over the
/// path tracer's sampling routine — the frame loop: bootstrap, chain starts, chains in
/// parallel, normalisation, image.
///
/// Estimator (Veach 1997 §11.3; DESIGN.md §2). With f*(u) = luminance(L(u)) over primary
/// samples u ∈ [0,1)^∞ and b = ∫ f*(u) du:
///   pixel_j = W·H · ∫ h_j(u) L(u) du ≈ b · H_j / (M / (W·H)),
///   H_j = Σ over the M mutations of the expected-value splats (L/f*)·w in pixel j
/// (proposal weight a, current state 1−a: mlt_kernels' metropolis_step).
///   1. bootstrap: N independent large-step samples (parallel, deterministic), b̂ = mean f*;
///   2. chains start by resampling the bootstrap pool ∝ f* (no start-up bias,
///      mlt_kernels/normalisation.h), replaying the chosen sample from its key;
///   3. each chain takes its share of the M = spp·W·H − N mutations: a large step with
///      probability `large_step_probability`, else a small wrapped-Gaussian step σ;
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
/// the calling thread in mutations-per-pixel units; returning false stops the chains
/// and the image is normalised by the mutations taken.
RenderResult render_pssmlt(const Scene& scene, const RenderSettings& settings,
                           const ProgressCallback& progress = {});

}  // namespace cmlt
