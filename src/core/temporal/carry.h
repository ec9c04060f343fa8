#pragma once
/// \file Carrying a Markov-chain population from frame f to frame f+1 (DESIGN.md §4,
/// "carried chain states"). The frame loop's carry-over (src/cmlt/temporal/driver.py)
/// couples the chain starts of consecutive frames on the bootstrap points
/// (bootstrap_states, couple_starts below): exact, and the starts move only where the
/// target changed. The particle tools after this comment (evaluate_states, sample_pool,
/// plan_carry: reweighting and resampling carried states ∝ f*_{f+1}/f*_f) are the
/// general sequential-Monte-Carlo form, for states that are not bootstrap points.
/// Generic over the integrator: anything that runs chains of
/// MltSampler states through a PssmltTracer (pssmlt, cmlt) and exports / imports
/// mlt::ChainStates (integrators/mlt/chain_state.h) can use it.
///
/// The population at the end of frame f, {u_i}, i = 1..n, is (approximately) distributed
/// ∝ f*_f (the chains are in equilibrium). To start frame f+1 without bias we treat it as
/// a set of particles (sequential Monte Carlo):
///
///   1. evaluate f*_{f+1}(u_i) in the new scene (evaluate_states). A coordinate the state
///      has no value for (NaN: the old path did not read it) is uniform and independent
///      under π_f, so drawing it now is exact; the drawn value is written back into the
///      state, so the chain later replays exactly the path that was weighted;
///   2. add a pool of N independent uniform points v_j (sample_pool; a large step each,
///      keyed by (shot seed, pool domain, j) — the same points every frame), whose f*_f
///      (the previous frame's pool evaluation) and f*_{f+1} are known;
///   3. weight every particle x of the union by the deterministic-mixture (balance
///      heuristic) importance weight of the new target against the mixture proposal
///        W(x) = f*_{f+1}(x) / ( n · f*_f(x) / b_f  +  N · 1 )
///      (carried particles were drawn from π_f = f*_f / b_f, pool particles from the
///      uniform density 1); self-normalised, Σ_x W(x) δ_x / Σ W is an importance sample
///      of π_{f+1} = f*_{f+1} / b_{f+1} whose proposal covers the whole space (the pool),
///      so light that appears in frame f+1 (a lamp switched on, f*_f = 0 there) is found
///      — carried particles cannot see it, pool particles can, and they are weighted up
///      exactly where the carried population is thin;
///   4. resample n chain starts ∝ W with systematic resampling (one uniform, keyed by
///      (seed, resample domain, frame key): deterministic). Importance resampling from a
///      weighted sample targeting π_{f+1} gives starts distributed (as n, N grow) ∝
///      π_{f+1}: the chains start in equilibrium, as bootstrap resampling does for a
///      fresh frame. A carried particle whose new weight is ~0 simply dies; the pool
///      refreshes it.
///
/// With a static scene f*_{f+1} = f*_f, every carried weight is b_f / (n + N b_f / f*_f),
/// and the chains continue where they stopped (with stored seeds the numbers are the
/// same as in frame f, so the population settles and consecutive frames agree).
///
/// The ratio estimator of the normalisation (DESIGN.md §4) comes out of step 1:
///   b_ratio = b_f · mean_i( f*_{f+1}(u_i) / f*_f(u_i) ),
/// since E_{π_f}[f*_{f+1}/f*_f] = b_{f+1}/b_f on the support of f*_f (ratio_statistics).
#include "integrators/common/render_settings.h"
#include "integrators/mlt/chain_state.h"

#include <cstdint>
#include <memory>
#include <vector>

namespace cmlt {
class Scene;
}

namespace cmlt::temporal {

/// Counter domains of the temporal numbers (MltSampler's RngDomain is an 8-bit field;
/// these values are outside the ones mlt_sampler.h names).
inline constexpr uint32_t k_domain_evaluate = 0x40;  ///< id = carried state index
inline constexpr uint32_t k_domain_pool = 0x41;      ///< id = pool point index
inline constexpr uint32_t k_domain_carry = 0x42;     ///< id = frame key: the resampling uniform
inline constexpr uint32_t k_domain_keep = 0x43;      ///< id = chain, counter = frame key: keep tests
inline constexpr uint32_t k_domain_refresh = 0x44;   ///< id = group, counter = frame key: refresh draws

/// Evaluate every state of `states` in `scene` (f* and colour of the new frame, the
/// technique decoded again) with the settings' path sampler; coordinates without a value
/// that the path reads are drawn (keyed by (seed, k_domain_evaluate, i)) and stored.
/// Returns the completed states (f_star, colour, depth/s/t of the new frame).
std::shared_ptr<mlt::ChainStates> evaluate_states(const Scene& scene, const RenderSettings& settings,
                                                  const mlt::ChainStates& states);

/// N independent uniform points (one large step each, keyed by (pool_seed,
/// k_domain_pool, j)) evaluated in `scene`: their states (f_star = f*).
std::shared_ptr<mlt::ChainStates> sample_pool(const Scene& scene, const RenderSettings& settings,
                                              uint64_t pool_seed, uint64_t count);

/// Bootstrap samples the frame's render evaluates (mlt_frame.h FrameBudget: min(bootstrap
/// samples, half of what the pilot and the direct pass leave)).
uint64_t bootstrap_count(const RenderSettings& settings);

/// The render's bootstrap points — large steps keyed (settings.seed, bootstrap, i),
/// i < count — evaluated in `scene` as the render evaluates them: their states, f_star
/// = f*. Given to the render (RenderSettings::mlt_bootstrap_f) the render does not
/// evaluate them again; a chain started from state i starts from bootstrap point i.
std::shared_ptr<mlt::ChainStates> bootstrap_states(const Scene& scene, const RenderSettings& settings,
                                                   uint64_t count);

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
/// draws of couple_starts).
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

/// Uniform in [0, 1) keyed by (seed, k_domain_carry, key).
double carry_uniform(uint64_t seed, uint32_t key);

/// Ratio statistics over the carried states: w_i = f_new_i / f_old_i for f_old_i > 0.
struct RatioStats {
    uint64_t count = 0;  ///< states with f_old > 0
    double mean = 0.0;   ///< mean w
    double variance = 0.0;  ///< sample variance of w (n − 1)
    uint64_t zero = 0;   ///< states whose new f* is 0 (lost their contribution)
};
RatioStats ratio_statistics(const std::vector<double>& f_old, const std::vector<double>& f_new);

/// The plan of step 3–4: mixture weights of carried (f_old, f_new) and pool (pool_old,
/// pool_new) particles, n starts resampled with uniform u0. pool_old may be empty (no
/// previous pool evaluation: pool points then count as uncovered by the carried
/// population, f*_f = 0). Returned indices < carried count are carried particles, the
/// others pool particles (index − carried count).
struct CarryPlan {
    std::vector<uint64_t> picks;
    uint64_t from_carried = 0, from_pool = 0;
    double weight_carried = 0.0, weight_pool = 0.0;  ///< Σ W of each group
};
CarryPlan plan_carry(const std::vector<double>& f_old, const std::vector<double>& f_new,
                     const std::vector<double>& pool_old, const std::vector<double>& pool_new,
                     double b_old, uint64_t n, double u0);

/// A ChainStates of picked states: pick p < a.size() → a.chains[p], else b.chains[p − a.size()];
/// chain c gets chain_id = the picked state's chain_id for carried picks, and
/// `pool_id_base + j` for pool point j. f_star / colour are kept (the new frame's).
std::shared_ptr<mlt::ChainStates> gather_states(const mlt::ChainStates& a, const mlt::ChainStates& b,
                                                const std::vector<uint64_t>& picks, uint64_t pool_id_base);

}  // namespace cmlt::temporal
