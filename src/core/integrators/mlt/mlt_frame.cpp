// The frame of the Metropolis integrators; see mlt_frame.h.
#include "integrators/mlt/mlt_frame.h"

#include "scene/scene.h"

#include <algorithm>

namespace cmlt::mlt {

FrameBudget FrameBudget::plan(const RenderSettings& s) {
    FrameBudget b;
    b.pilot = MltContext::pilot_cost(s);
    b.direct = MltContext::direct_cost(s);  // a sample budget's; timed: as it runs
    if (!MltContext::chains_needed(s)) return b;  // max_depth 1 with a direct pass
    const uint64_t left = MltContext::evaluation_budget(s);
    b.bootstrap = std::max<uint64_t>(1, std::min<uint64_t>(uint64_t(s.bootstrap_samples), left / 2));
    b.chains = left - b.bootstrap;
    return b;
}

MltFrame::MltFrame(const Scene& scene_, const RenderSettings& s)
    : scene(scene_), settings(s), threads(frame_threads(s)), arena(threads), t0(std::chrono::steady_clock::now()),
      ctx(scene_, s, m_pilot_counters), direct_pass(scene_, s), budget(FrameBudget::plan(s)),
      film(s.width, s.height), direct{direct_pass, s, arena, counters} {
    counters.add(m_pilot_counters);
}

namespace {

void develop_image(RenderResult& res, const SplatFilm& film, double b, uint64_t steps, const PtPassImage& direct) {
    const size_t pixels = size_t(res.width) * size_t(res.height);
    res.image.assign(pixels * 3, 0.f);
    res.variance.assign(pixels * 3, 0.f);
    const double scale = steps > 0 ? b * double(pixels) / double(steps) : 0.0;
    for (size_t i = 0; i < pixels; ++i)
        for (int k = 0; k < 3; ++k) {
            const double chain = scale * film.sum(i, k);
            const double d = direct.mean.empty() ? 0.0 : double(direct.mean[3 * i + k]);
            res.image[3 * i + k] = float(chain + d);
        }
    if (!direct.mean.empty()) {
        res.direct = direct.mean;
        res.variance = direct.variance;
    }
}

}  // namespace

RenderResult MltFrame::finish(PopulationResult&& chains) {
    const PtPassImage direct_image = direct_pass.develop();
    const double secs = seconds_since(t0);

    RenderResult res;
    res.width = settings.width;
    res.height = settings.height;
    develop_image(res, film, chains.b.mean, chains.steps, direct_image);
    res.cancelled = chains.cancelled;
    res.bootstrap_f.assign(chains.bootstrap_f.begin(), chains.bootstrap_f.end());
    res.mlt_states = std::move(chains.states);
    res.mlt_start_states = std::move(chains.start_states);

    RenderStats& st = res.stats;
    fill_frame_stats(st, counters, rate, secs);
    st.nan_samples = counters.invalid.load() + chains.invalid + direct_image.nan_samples;
    st.threads = threads;
    st.integrator = settings.integrator;
    st.spp = settings.spp;
    st.seed = settings.seed;

    MltStats& m = st.mlt;
    m.enabled = true;
    m.b = chains.b.mean;
    m.b_stderr = chains.b.std_error;
    m.b_bootstrap = chains.b_bootstrap.mean;
    m.b_bootstrap_stderr = chains.b_bootstrap.std_error;
    m.bootstrap_samples = budget.bootstrap;
    m.bootstrap_nonzero = chains.b_bootstrap.nonzero;
    m.sigma = settings.sigma;
    m.max_rejection_streak = chains.streaks.max_streak;
    m.long_streak_rejections = chains.streaks.long_streak_rejections;
    m.states_visited = chains.streaks.occupancy.states();
    m.top_occupancy = chains.streaks.occupancy.top_fraction(0.001);
    m.path_sampler = settings.mlt_path_sampler;
    m.importance = settings.importance;
    m.pilot_evaluations = budget.pilot;
    m.direct_evaluations = direct_pass.evaluations();
    m.min_depth = MltContext::min_depth(settings);
    m.time_budget = settings.time_budget;
    m.chains = chains.chains;
    m.mutations = chains.steps;
    m.mutations_per_pixel = double(chains.steps) / double(uint64_t(settings.width) * uint64_t(settings.height));
    m.large_steps = chains.kernel[mcmc::MutationKind::large_step].steps;
    m.acceptance_large = chains.kernel[mcmc::MutationKind::large_step].acceptance_rate();
    m.imported_chains = chains.imported ? chains.chains : 0;
    m.clamped_splats = film.clamped();
    m.path_evaluations = budget.pilot + direct_pass.evaluations() + budget.bootstrap + chains.evaluations;
    return res;
}

}  // namespace cmlt::mlt
