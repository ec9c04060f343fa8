#pragma once
/// \file The frame of a Metropolis integrator (pssmlt, cmlt): what both frame loops
/// share around their chains (chain_population.h) — the budget split, the thread arena
/// and counters, the pilot (MltContext) and the direct pass, the splat film, and the
/// image and statistics at the end.
///
/// Budget of a frame, spp·W·H path evaluations (a path evaluation is one traced
/// path: a bootstrap sample, a proposal or a candidate, a pilot or direct sample):
///   1. pilot of the pixel importance: pilot_spp·W·H (pixel_importance.h);
///   2. direct pass: round(direct_fraction · spp)·W·H path-traced samples of depth ≤ 1,
///      added to the image as they are (direct_pass.h); the chains then render depth ≥ 2
///      only. It runs in slices between the chain rounds, so with a time budget it keeps
///      its share of the evaluations whatever the time allows;
///   3. bootstrap: min(bootstrap_samples, half of what is left) large-step samples;
///   4. the chains: the rest, split evenly over the chains.
/// With a time budget the chains run until it is used up (frame_loop.h); 1–3 always run.
#include "integrators/common/frame_loop.h"
#include "integrators/common/render_settings.h"
#include "integrators/mlt/chain_state.h"
#include "integrators/mlt/chain_stats.h"
#include "integrators/mlt/direct_pass.h"
#include "integrators/mlt/mlt_context.h"
#include "integrators/mlt/splat_film.h"
#include "integrators/path/path_tracer.h"
#include "mcmc/normalisation.h"
#include "mcmc/step_stats.h"

#include <tbb/task_arena.h>

#include <chrono>
#include <cstdint>
#include <memory>
#include <vector>

namespace cmlt {

class Scene;

namespace mlt {

struct FrameBudget {
    uint64_t pilot = 0, direct = 0, bootstrap = 0, chains = 0;

    static FrameBudget plan(const RenderSettings& s);
};

/// What a chain population hands the frame at its end, merged in chain order
/// (ChainPopulation::finish).
struct PopulationResult {
    std::vector<double> bootstrap_f;         ///< f* of the bootstrap samples, by index
    mcmc::NormalisationEstimate b_bootstrap;  ///< b from the bootstrap alone
    mcmc::NormalisationEstimate b;            ///< b from the bootstrap and every large step
    mcmc::KernelStats kernel;                 ///< every chain's steps, by kernel
    StreakTracker streaks;
    uint64_t chains = 0, steps = 0, evaluations = 0, invalid = 0;
    bool imported = false;   ///< the chains started from given states
    bool cancelled = false;  ///< progress stopped the frame
    std::shared_ptr<ChainStates> states, start_states;
};

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
    const FrameBudget budget;
    SplatFilm film;
    DirectSchedule direct;
};

}  // namespace mlt
}  // namespace cmlt
