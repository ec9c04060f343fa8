#pragma once
/// \file The frame of a Metropolis integrator (pssmlt, cmlt): what both frame loops
/// share around their chains (chain_population.h) — the budget split, the thread arena
/// and counters, the pilot (MltContext) and the direct pass, the splat film, and the
/// image and statistics at the end.
///
/// Budget of a frame, spp·W·H path evaluations (a path evaluation is one traced
/// path: a bootstrap sample, a proposal or a candidate, a pilot or direct sample):
///   1. pilot of the pixel importance: pilot_spp·W·H (pixel_importance.h);
///   2. direct pass: round(direct_fraction · spp)·W·H path-traced samples of depth ≤ 1
///      (mlt_paths all; the chains then render depth ≥ 2) or of every path but the
///      caustic ones (mlt_paths caustics; the chains render those:
///      common/path_partition.h), added to the image as they are (direct_pass.h). It runs
///      in slices between the chain rounds, so with a time budget it keeps its share of
///      the evaluations whatever the time allows. Without chains (mlt_paths none) it is
///      the whole frame, run as pt's pass loop (DirectSchedule::run_alone);
///   3. bootstrap: min(bootstrap_samples, half of what is left) large-step samples
///      (bootstrap_samples 0: bootstrap_size below; its probe is reported in the
///      statistics' path_evaluations, not taken from the budget);
///   4. the chains: the rest, split evenly over the chains. Where none starts (the
///      bootstrap found no path the chains render, and none was carried), the direct
///      pass renders the frame alone with the chains' evaluations as well
///      (direct_passes_without_chains; the sidecar's direct_alone).
/// With a time budget the chains run until it is used up (frame_loop.h); 1–3 always run.
#include "film/splat_film.h"
#include "integrators/common/frame_loop.h"
#include "integrators/common/render_settings.h"
#include "integrators/mlt/chain_state.h"
#include "integrators/mlt/direct_pass.h"
#include "integrators/mlt/mlt_context.h"
#include "integrators/path/path_tracer.h"
#include "mcmc/chain_diagnostics.h"
#include "mcmc/normalisation.h"
#include "mcmc/step_stats.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

namespace cmlt {

class Scene;

namespace mlt {

/// Chains [first, second) of a frame's n that this render runs: all, or a part's
/// (RenderSettings::partial).
inline std::pair<size_t, size_t> part_chains(const RenderSettings& s, size_t n) {
    if (!s.partial) return {0, n};
    return {size_t(std::min<uint64_t>(s.part_chain_begin, n)), size_t(std::min<uint64_t>(s.part_chain_end, n))};
}

struct FrameBudget {
    uint64_t pilot = 0, direct = 0, bootstrap = 0, chains = 0;

    /// `bootstrap`: the samples wanted (bootstrap_size), at most half of what is left for
    /// bootstrap and chains; with bootstrap_samples 0 (auto) RenderSettings::mlt_bootstrap_f,
    /// where given, decides it (the temporal driver sized it as bootstrap_size would).
    static FrameBudget plan(const RenderSettings& s, uint64_t bootstrap);
    /// With the setting's size (auto: k_bootstrap_default; no probe).
    static FrameBudget plan(const RenderSettings& s);
};

/// The bootstrap's size where RenderSettings::bootstrap_samples is 0 (auto): the default,
/// or — where fewer than 1 % of uniform samples carry light (door_ajar, caustic_glass:
/// 0.1 %), so that the default's ~100 such samples start every chain from one of a
/// hundred paths (tests/bench/results/door_ajar_metropolis.md) — enough samples for
/// about one that carries light per chain: chains · P / (the probe's non-zero count),
/// from a probe of P samples keyed (seed, bootstrap_probe, i), disjoint from the
/// bootstrap's own (so the size is independent of the pool: the pool's b and
/// resampled starts are exact for it as for any fixed size). At most
/// k_bootstrap_share of the evaluations left for bootstrap and chains and, with a time
/// budget, of the seconds (at the probe's rate); never less than the default.
inline constexpr uint64_t k_bootstrap_default = 100000;
inline constexpr uint64_t k_bootstrap_probe = 16384;
inline constexpr double k_bootstrap_share = 0.25;

struct BootstrapSize {
    uint64_t wanted = 0;                       ///< samples wanted (FrameBudget::plan caps them)
    uint64_t probe = 0, probe_nonzero = 0;     ///< the probe's samples and those with f* > 0 (0: none ran)
};

BootstrapSize bootstrap_size(const RenderSettings& s, const PssmltTracer& tracer, tbb::task_arena& arena,
                             FrameCounters& counters);

/// The start probe of RenderSettings::mlt_min_starts: a frame whose chains would start
/// from a handful of the bootstrap's samples — all of its chains resampled from them,
/// copies of a few paths, with b from as few — is rendered without chains (mlt_paths
/// none: the direct pass, or bdpt with chainless_integrator bdpt). The decision reads a
/// probe keyed (seed, bootstrap_probe, i), disjoint from the bootstrap's keys, so it is
/// independent of the chains' estimate it replaces: each of the two estimators is
/// unbiased, and so is the frame whichever the probe picks (README, "Hard cases").
struct StartProbe {
    uint64_t probe = 0, nonzero = 0;  ///< the probe's samples, those with f* > 0
    uint64_t bootstrap = 0;           ///< the bootstrap size the frame would take
    double expected = 0;              ///< nonzero / probe · bootstrap
    bool too_few = false;             ///< expected < mlt_min_starts: render without chains
    PathCounters counters;            ///< the probe's rays
};

/// Does the start probe decide `given`'s frame: pssmlt/cmlt, mlt_min_starts > 0,
/// mlt_paths auto resolving to caustics with chains needed, an auto bootstrap size, no
/// bootstrap values or chain states given (the temporal driver's frames: it probes in
/// bootstrap_states and decides there, cmlt.temporal.driver).
bool start_probe_applies(const Scene& scene, const RenderSettings& given);
/// Run the probe for `given` (render.cpp, before the frame is dispatched).
StartProbe probe_starts(const Scene& scene, const RenderSettings& given);

/// What a chain population hands the frame at its end, merged in chain order
/// (ChainPopulation::finish).
struct PopulationResult {
    std::vector<double> bootstrap_f;         ///< f* of the bootstrap samples, by index
    mcmc::NormalisationEstimate b_bootstrap;  ///< b from the bootstrap alone
    mcmc::NormalisationEstimate b;            ///< b from the bootstrap and every large step
    mcmc::KernelStats kernel;                 ///< every chain's steps, by kernel
    mcmc::StreakTracker streaks;
    mcmc::ShareSummary shares;                ///< the chains' splat shares (stuck chains)
    uint64_t chains = 0, steps = 0, evaluations = 0, invalid = 0;
    bool imported = false;   ///< the chains started from given states
    bool cancelled = false;  ///< progress stopped the frame
    std::shared_ptr<ChainStates> states, start_states;
    /// RenderSettings::partial: the bootstrap's accumulator, then those of the part's
    /// chains in chain order (RenderResult::mlt_part)
    std::vector<mcmc::NormalisationAccumulator> part_norms;
    std::vector<double> group_steps;  ///< steps per error group (chain c in group c mod G)
    bool target_reached = false;      ///< the frame stopped at its target error
    /// the direct pass rendered the frame alone: chainless, or no chain started (its
    /// estimate and target are the pass's own)
    bool direct_alone = false;
    std::vector<std::array<double, 4>> error_history;  ///< the target's estimates
};

/// Layers of the frame's splat film: the error groups (RenderSettings.error_groups; a
/// chain splats into its group's layer), or 1 without an estimate.
inline int error_layers(const RenderSettings& s) { return s.error_groups >= 3 ? s.error_groups : 1; }

/// The error group of each chain resampled from the bootstrap pool (`pick[k]`: chain k's
/// bootstrap sample), `groups` G: chains that start from the same sample are copies of
/// one path until they have moved apart, so they share a group — groups made of disjoint
/// sets of start samples are independent given the pool, which the estimate assumes
/// (chain k in group k mod G put copies of one start in every group, and the groups'
/// spread missed the error of which few paths the chains started from). The start
/// samples, by how many chains they start, go one by one to the group with the fewest
/// chains so far (ties: the lower group). Fewer distinct starts than G leave groups
/// empty (the estimate uses the others). Chains imported from a previous frame stay in
/// group k mod G.
inline std::vector<int> start_sample_groups(const std::vector<size_t>& pick, int groups) {
    std::vector<int> out(pick.size(), 0);
    if (groups <= 1) return out;
    std::vector<std::pair<size_t, size_t>> starts;  // (sample, chains), by sample
    {
        std::vector<size_t> sorted(pick);
        std::sort(sorted.begin(), sorted.end());
        for (size_t s : sorted)
            if (starts.empty() || starts.back().first != s) starts.push_back({s, 1});
            else ++starts.back().second;
    }
    std::stable_sort(starts.begin(), starts.end(), [](const auto& a, const auto& b) { return a.second > b.second; });
    std::vector<size_t> load(size_t(groups), 0);
    std::vector<std::pair<size_t, int>> group_of;  // (sample, group), sorted by sample after
    group_of.reserve(starts.size());
    for (const auto& st : starts) {
        const int g = int(std::min_element(load.begin(), load.end()) - load.begin());
        load[size_t(g)] += st.second;
        group_of.push_back({st.first, g});
    }
    std::sort(group_of.begin(), group_of.end());
    for (size_t k = 0; k < pick.size(); ++k)
        out[k] = std::lower_bound(group_of.begin(), group_of.end(), std::make_pair(pick[k], -1))->second;
    return out;
}

/// The relMSE estimate of a Metropolis frame from its film's layers (error_target.h):
/// group g's image is b·W·H/steps[g] times its layer plus the direct pass; every group
/// shares the direct pass's variance and b's, (b_se/b)² on the chains' part. Optionally
/// writes the group images (G', H, W, 3) and their steps (`used_steps`) of the G' groups
/// with steps (empty groups are left out). No estimate without >= 3 such groups.
ErrorValue estimate_groups(const SplatFilm& film, const std::vector<double>& steps,
                           const mcmc::NormalisationEstimate& b, const PtPassImage& direct,
                           std::vector<float>* group_images = nullptr, std::vector<double>* used_steps = nullptr);

/// After a chain round of a frame with a target error: the estimate `e`, recorded in `t`;
/// true when the target is reached (not before round 2G, the first 2G rounds being equal
/// slices: the chains must have moved before their groups' spread means much), else the
/// schedule's next share of the chains' budget (`evaluations` of `chain_budget` spent so
/// far). `work`: path evaluations per pixel so far (the history's unit).
bool target_round(ErrorTarget& t, ChainSchedule& schedule, const ErrorValue& e, double work, uint64_t evaluations,
                  uint64_t chain_budget, int groups);

/// The first share of the chains' budget a targeted frame runs (and each of its first 2G
/// rounds): 2 evaluations per pixel (a chain whose share is less than one block runs a
/// block in the rounds where its share passes one).
inline double target_first_fraction(uint64_t pixels, uint64_t chain_budget) {
    if (chain_budget == 0) return 1.0;
    return std::min(1.0, double(2 * pixels) / double(chain_budget));
}

/// One Metropolis frame's machinery, built in this order: the thread arena and the
/// counters, the pilot (in the context), the direct pass, the budget, the splat film.
class MltFrame {
public:
    MltFrame(const Scene& scene, const RenderSettings& settings);
    MltFrame(const MltFrame&) = delete;
    MltFrame& operator=(const MltFrame&) = delete;

    /// The image (b · W·H / steps times the splat sums, plus the direct pass; the
    /// variance AOV is the direct pass's: correlated chain samples have none per pixel)
    /// and the statistics both Metropolis integrators fill the same way. The caller adds
    /// its own (small / large steps, acceptance, kernel JSON, large_step_probability).
    RenderResult finish(PopulationResult&& chains);

    /// Passes of the direct pass when no chain started (the bootstrap found no path the
    /// chains render and none was carried): its own share plus the chains' evaluations,
    /// whole passes of the frame — the frame spends its budget as planned (the pilot and
    /// the bootstrap are spent already). Deterministic: the same bootstrap, the same passes.
    int direct_passes_without_chains() const {
        const uint64_t pixels = uint64_t(settings.width) * uint64_t(settings.height);
        return MltContext::direct_spp(settings) + int(budget.chains / std::max<uint64_t>(pixels, 1));
    }

    const Scene& scene;
    const RenderSettings& settings;
    const int threads;
    tbb::task_arena arena;
    FrameCounters counters;
    const CycleRate rate;
    const std::chrono::steady_clock::time_point t0;

private:
    PathCounters m_pilot_counters;  ///< the pilot's rays, added to `counters`

public:
    const MltContext ctx;
    DirectPass direct_pass;
    const BootstrapSize bootstrap_size;
    const FrameBudget budget;
    SplatFilm film;
    DirectSchedule direct;
};

/// The image of a frame rendered in parts (render.h combine_mlt_parts).
RenderResult combine_parts(int width, int height, const std::vector<const MltPart*>& parts,
                           const std::vector<float>& direct);

}  // namespace mlt
}  // namespace cmlt
