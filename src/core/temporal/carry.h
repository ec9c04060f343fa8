#pragma once
/// \file Carrying Markov chains from frame f to frame f+1 (DESIGN.md §4, "carried chain
/// states"), generic over the integrator: anything that runs chains of MltSampler states
/// through a PssmltTracer (pssmlt, cmlt) and imports mlt::ChainStates
/// (integrators/mlt/chain_state.h) can use it. The frame loop (src/cmlt/temporal/driver.py):
///
///   1. evaluates the frame's bootstrap points before the render (bootstrap_states: with
///      stored seeds the same points every frame) and gives their f* to the render
///      (RenderSettings::mlt_bootstrap_f), which does not evaluate them again;
///   2. chooses the chain starts among them, coupled to the previous frame's starts
///      (couple_starts): a start stays where its target did not change, moves where it
///      did, and the starts are distributed exactly as a fresh frame's;
///   3. offsets the chains' film position (RenderSettings::film_offset_x/y, a
///      measure-preserving reparametrisation) by the image's screen motion, measured
///      with screen anchors (screen_anchors, project_anchors), so that under a moving
///      camera a kept start lands on the surface it saw before.
/// Why coupling rather than reweighting carried particles: resampling a population
/// reweighted by f*_{f+1}/f*_f duplicates a few states where it does not cover the new
/// target, and short chains do not spread them out again (measured on moving_light:
/// relMSE growing over the frames, tests/bench/results/flicker_baseline.md); the
/// coupled starts are as good as a fresh frame's every frame.
///
/// evaluate_states (a state's f* in the new scene) and ratio_statistics (the mean of
/// f*_{f+1}/f*_f over states ∝ f*_f, an estimate of b_{f+1}/b_f on the support of f*_f)
/// are the tools for states that are not bootstrap points.
#include "integrators/common/render_settings.h"
#include "integrators/mlt/chain_state.h"
#include "integrators/path/path_tracer.h"

#include <cstdint>
#include <memory>
#include <vector>

namespace cmlt {
class Scene;
}

namespace cmlt::temporal {

/// Evaluate every state of `states` in `scene` (f* and colour of the new frame, the
/// technique decoded again) with the settings' path sampler; coordinates without a value
/// that the path reads are drawn (keyed by (seed, RngDomain::carry_evaluate, i)) and stored.
/// Returns the completed states (f_star, colour, depth/s/t of the new frame).
std::shared_ptr<mlt::ChainStates> evaluate_states(const Scene& scene, const RenderSettings& settings,
                                                  const mlt::ChainStates& states);

/// Bootstrap samples the frame's render evaluates (mlt_frame.h FrameBudget: min(bootstrap
/// samples, half of what the pilot and the direct pass leave)); with bootstrap_samples 0
/// (auto) the default's, without the probe that may size it up (bootstrap_states with
/// count 0 runs it).
uint64_t bootstrap_count(const RenderSettings& settings);

/// Chains a render with these settings starts without initial states: settings.chains,
/// at most one per evaluation the budget leaves the chains (pssmlt), at most one per
/// block of 1 + inner_length·tries evaluations (cmlt), at least 1; 0 for pt and bdpt,
/// and when no chains are needed. As pssmlt_integrator.cpp and cmlt_integrator.cpp
/// count them (tests/python/temporal compares it with the render's `chains` stat): the
/// temporal driver asks this many starts, never more, so a huge --chains costs nothing.
uint64_t chain_count(const RenderSettings& settings);

/// The render's bootstrap points — large steps keyed (settings.seed, bootstrap, i),
/// i < count — evaluated in `scene` as the render evaluates them: their states, f_star
/// = f*. Given to the render (RenderSettings::mlt_bootstrap_f) the render does not
/// evaluate them again; a chain started from state i starts from bootstrap point i.
/// `counters`, if given, receives the rays and samples traced. `count` 0: the size
/// the render would choose with settings.bootstrap_samples (auto: mlt_frame.h
/// bootstrap_size's probe, run here with the frame's scene and pilot).
std::shared_ptr<mlt::ChainStates> bootstrap_states(const Scene& scene, const RenderSettings& settings,
                                                   uint64_t count, PathCounters* counters = nullptr,
                                                   uint64_t* probe = nullptr, uint64_t* probe_nonzero = nullptr);

/// Chain starts of frame f+1 coupled to those of frame f (maximal coupling of the two
/// frames' bootstrap resampling distributions).
///
/// With stored seeds the bootstrap points v_i are the same in both frames; a fresh
/// frame starts its chains from v_i with probability p_i = f*_f(v_i) / Σ f*_f (old) or
/// q_i = f*_{f+1}(v_i) / Σ f*_{f+1} (new). Chain k started frame f from v_{i_k}; it
/// keeps that start with probability min(1, q_{i_k} / p_{i_k}) (a keyed uniform per
/// chain and frame), and a chain that does not is refreshed from the residual
/// distribution ∝ (q_i − p_i)^+ (systematic resampling over the refreshed chains).
/// If frame f's starts were distributed as its fresh resampling (expected count of v_i
/// n p_i), the expected count of v_i is now n·min(p_i, q_i) + n·TV·(q_i − p_i)^+ / TV =
/// n q_i: the starts are distributed exactly as a fresh frame's, so the expected image
/// is the one a fresh render gives, while a start whose target did not change (q_i =
/// p_i: a static part of the image) stays where it was, and its chain — same start,
/// same numbers — retraces the previous frame's path. Where the target changed, the
/// fewest chains move (1 − TV of them keep their start; no scheme that keeps the
/// starts' distribution exact can keep more).
///
/// `prev_picks` empty (first frame), Σ f_old = 0, or a size mismatch: a fresh
/// systematic resampling ∝ f_new. Chains beyond prev_picks.size() start fresh (∝ q).
struct CoupledStarts {
    std::vector<uint64_t> picks;   ///< bootstrap index of each chain's start (n of them)
    uint64_t kept = 0;             ///< chains that kept their previous start
    uint64_t refreshed = 0;        ///< chains refreshed from the residual
    uint64_t fresh = 0;            ///< chains started fresh (no previous start)
    double tv = 1.0;               ///< total variation distance Σ (q − p)^+ (1: no previous)
};
CoupledStarts couple_starts(const std::vector<double>& f_old, const std::vector<double>& f_new,
                            const std::vector<uint64_t>& prev_picks, uint64_t n, uint64_t seed,
                            uint32_t frame_key);

/// Uniform in [0, 1) keyed by (seed, domain, id, counter) (the keep tests and refresh
/// draws of couple_starts: domains RngDomain::carry_keep and carry_refresh,
/// sampling/rng_domains.h).
double keyed_uniform(uint64_t seed, uint32_t domain, uint32_t id, uint32_t counter);

/// Screen motion (camera reprojection). An anchor is what the camera ray through a film
/// position hits first, in the hit instance's object space, so that it follows the
/// instance (and the camera) into the next frame.
struct Anchor {
    int32_t instance = -1;  ///< hit instance, -1: the ray hit nothing (or a light)
    Vec3 p_object{0.f};     ///< hit point in the instance's object space
    Vec2 p_raster{0.f, 0.f};///< film position the ray went through (raster units)
};
/// Anchors of an n_x × n_y grid of film positions (cell centres, row by row).
std::vector<Anchor> screen_anchors(const Scene& scene, const RenderSettings& settings, int n_x, int n_y);
/// Raster positions of `anchors` in `scene` (its instances' transforms and camera):
/// NaN where the anchor has no hit, its instance is gone, or it is behind the camera.
std::vector<Vec2> project_anchors(const Scene& scene, const RenderSettings& settings,
                                  const std::vector<Anchor>& anchors);

/// Systematic resampling: `n` indices into `weights` (≥ 0, finite), index i drawn
/// ⌊n W_i / ΣW + fractional offset⌋ times, with one uniform u0 ∈ [0, 1). Sorted.
/// Empty if Σ weights = 0.
std::vector<uint64_t> systematic_resample(const std::vector<double>& weights, uint64_t n, double u0);

/// Ratio statistics over the carried states: w_i = f_new_i / f_old_i for f_old_i > 0.
struct RatioStats {
    uint64_t count = 0;  ///< states with f_old > 0
    double mean = 0.0;   ///< mean w
    double variance = 0.0;  ///< sample variance of w (n − 1)
    uint64_t zero = 0;   ///< states whose new f* is 0 (lost their contribution)
};
RatioStats ratio_statistics(const std::vector<double>& f_old, const std::vector<double>& f_new);

/// A ChainStates of picked states: pick p < a.size() → a.chains[p], else b.chains[p − a.size()];
/// chain c gets chain_id = the picked state's chain_id for carried picks, and
/// `pool_id_base + j` for pool point j. f_star / colour are kept (the new frame's).
std::shared_ptr<mlt::ChainStates> gather_states(const mlt::ChainStates& a, const mlt::ChainStates& b,
                                                const std::vector<uint64_t>& picks, uint64_t pool_id_base);

}  // namespace cmlt::temporal
