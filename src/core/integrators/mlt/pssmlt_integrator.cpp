// PSSMLT frame loop; see pssmlt_integrator.h for the estimator and its steps.
#include "integrators/mlt/pssmlt_integrator.h"

#include "cameras/camera.h"
#include "integrators/bdpt/bdpt_tracer.h"
#include "integrators/mlt/chain_state.h"
#include "integrators/mlt/mlt_context.h"
#include "integrators/mlt/mlt_frame.h"
#include "integrators/mlt/mlt_sampler.h"
#include "integrators/mlt/pssmlt_tracer.h"
#include "integrators/mlt/splat_film.h"
#include "integrators/mlt_kernels/mlt_kernels.h"
#include "integrators/path/path_tracer_impl.h"
#include "scene/scene.h"
#include "util/error.h"
#include "util/fp_mode.h"

#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <memory>
#include <sstream>

namespace cmlt {

namespace {

using mlt::MltSampler;
using mlt::PathSample;
using mlt::RngDomain;

/// The proposal of metropolis_step: the sampler has begun an iteration (large or small);
/// "sampling" the proposal is tracing the path its primary samples describe. Both
/// mutations are symmetric in primary sample space (T(x→y) = T(y→x)).
struct SamplerProposal {
    static constexpr bool k_symmetric = true;
    const mlt::PssmltTracer* tracer;
    MltSampler* sampler;
    PathCounters* counters;
    PathSample* last;  ///< the proposal just traced (for the large-step b and NaN counts)

    template <class State, class Rng>
    void sample(const State& /*from*/, State& to, Rng& /*rng*/) const {
        to = tracer->evaluate(*sampler, *counters);
        *last = to;
    }
};

/// One Markov chain and everything it accumulates.
struct ChainRun {
    ChainRun(MltSampler s, PathSample x) : sampler(std::move(s)), ws(1, PathSample{}) {
        chain.x = x;
        chain.fx = x.f;
    }
    MltSampler sampler;
    mlt::Chain<PathSample> chain;
    mlt::Workspace<PathSample> ws;
    uint64_t budget = 0, done = 0;
    mlt::KernelStats stats;
    mlt::NormalisationAccumulator large;  ///< f* of the large-step proposals
    mlt::StreakTracker streaks;
    uint64_t invalid = 0;
    uint64_t chain_id = 0;
};

/// The chain's current state as a ChainState (see chain_state.h).
mlt::ChainState export_chain(const ChainRun& c) {
    mlt::ChainState out;
    out.chain_id = c.chain_id;
    const auto u = c.sampler.current_state();
    for (size_t k = 0; k < u.size(); ++k) out.u[k].assign(u[k].begin(), u[k].end());
    const PathSample& x = c.chain.x;
    if (x.depth >= 0) {
        out.depth = uint32_t(x.depth);
        out.s = uint32_t(x.s);
        out.t = uint32_t(x.t);
    }
    out.f_star = c.chain.fx;
    out.colour = x.L;
    return out;
}

}  // namespace

RenderResult render_pssmlt(const Scene& scene, const RenderSettings& settings,
                           const ProgressCallback& progress) {
    const int W = settings.width, H = settings.height;
    const uint64_t pixels = uint64_t(W) * uint64_t(H);
    const bool use_bdpt = settings.mlt_path_sampler == "bdpt";
    const int threads = settings.threads > 0 ? settings.threads : tbb::info::default_concurrency();
    tbb::task_arena arena(threads);
    FrameCounters counters;
    const CycleRate rate;
    const auto t0 = std::chrono::steady_clock::now();

    // 1. pilot (in the context) and direct pass
    PathCounters pilot_counters;
    const mlt::MltContext ctx(scene, settings, pilot_counters);
    counters.add(pilot_counters);
    const mlt::PssmltTracer& tracer = ctx.tracer;
    mlt::DirectPass direct_pass(scene, settings);

    // multiplexed MLT: the technique samples change at large steps only (mlt_sampler.h)
    const auto make_sampler = [&](RngDomain domain, uint32_t id) {
        MltSampler smp(settings.seed, settings.sigma, settings.large_step_probability, domain, id);
        if (use_bdpt)
            smp.freeze_in_small_steps(MltSampler::connection,
                                      mlt::k_technique_dimensions * MltSampler::k_slots_per_dimension);
        return smp;
    };
    const mlt::ChainStates* initial = settings.mlt_initial_states.get();
    if (initial && initial->chains.empty()) initial = nullptr;
    if (initial && initial->path_sampler != settings.mlt_path_sampler)
        CMLT_THROW(SettingsError, "RenderSettings.mlt_initial_states: states of the '"
                                      << initial->path_sampler << "' path sampler cannot start '"
                                      << settings.mlt_path_sampler << "' chains");
    const uint64_t seed = settings.seed;
    const mlt::FrameBudget budget = mlt::FrameBudget::plan(settings);
    const uint64_t n_mut = budget.chains;
    const uint64_t n_chains = initial ? std::min<uint64_t>(initial->chains.size(), n_mut)
                                      : std::min<uint64_t>(uint64_t(settings.chains), n_mut);
    mlt::SplatFilm film(W, H);
    mlt::DirectSchedule direct{direct_pass, settings, arena, counters};

    // 2. bootstrap: N independent large-step samples, keyed (seed, bootstrap, i)
    const std::vector<double> boot_f =
        mlt::bootstrap_values(settings, arena, budget.bootstrap, counters, [&](uint64_t i, PathCounters& c, bool& invalid) {
            MltSampler smp = make_sampler(RngDomain::bootstrap, uint32_t(i));
            smp.start_iteration(true);
            const PathSample s = tracer.evaluate(smp, c);
            invalid = s.invalid;
            return s.f;
        });
    mlt::NormalisationAccumulator boot_acc;
    for (double f : boot_f) boot_acc.add(f);  // index order: deterministic
    const mlt::NormalisationEstimate b_boot = boot_acc.estimate();

    // 3. chain starts: resample the pool ∝ f*, replay the chosen sample, rekey to the chain
    //    (or: the given states, re-evaluated in this frame's scene)
    std::vector<std::unique_ptr<ChainRun>> chains;
    const auto chain_budget = [&](uint64_t k) { return n_mut / n_chains + (k < n_mut % n_chains ? 1 : 0); };
    if (initial && n_chains > 0) {
        chains.resize(n_chains);
        arena.execute([&] {
            tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n_chains, 8), [&](const tbb::blocked_range<uint64_t>& r) {
                ScopedFtzDaz ftz;
                const TaskTimer timer(counters);
                PathCounters c;
                uint64_t bad = 0;
                for (uint64_t k = r.begin(); k != r.end(); ++k) {
                    const mlt::ChainState& in = initial->chains[mlt::subsampled_state(k, n_chains, initial->chains.size())];
                    MltSampler smp = make_sampler(RngDomain::chain, uint32_t(k));
                    smp.import_state(in.u);
                    smp.begin_replay();
                    const PathSample x = tracer.evaluate(smp, c);
                    smp.end_replay();
                    bad += x.invalid ? 1 : 0;
                    chains[k] = std::make_unique<ChainRun>(std::move(smp), x);
                    chains[k]->chain_id = in.chain_id;
                    chains[k]->budget = chain_budget(k);
                }
                counters.add(c, bad);
            });
        });
    } else if (b_boot.nonzero > 0 && n_chains > 0) {
        mlt::CounterRng rng(seed, RngDomain::resample, 0);
        const std::vector<size_t> start = mlt::resample_start_indices(boot_f, size_t(n_chains), rng);
        chains.resize(n_chains);
        arena.execute([&] {
            tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n_chains, 8), [&](const tbb::blocked_range<uint64_t>& r) {
                ScopedFtzDaz ftz;
                const TaskTimer timer(counters);
                PathCounters c;
                for (uint64_t k = r.begin(); k != r.end(); ++k) {
                    MltSampler smp = make_sampler(RngDomain::bootstrap, uint32_t(start[k]));
                    smp.start_iteration(true);
                    const PathSample x = tracer.evaluate(smp, c);
                    CMLT_CHECK_MSG(x.f == boot_f[start[k]], "pssmlt: replaying bootstrap sample "
                                                                << start[k] << " gave a different path");
                    smp.accept();
                    smp.set_key(RngDomain::chain, uint32_t(k));
                    chains[k] = std::make_unique<ChainRun>(std::move(smp), x);
                    chains[k]->chain_id = k;
                    chains[k]->budget = chain_budget(k);
                }
                counters.add(c);
            });
        });
    }

    auto start_states = std::make_shared<mlt::ChainStates>();
    start_states->path_sampler = settings.mlt_path_sampler;
    for (const auto& c : chains) start_states->chains.push_back(export_chain(*c));

    // 4. run the chains in rounds (frame_loop.h), expected-value splatting into the film
    const auto target = [](const PathSample& s) { return s.f; };
    bool cancelled = false;
    ChainSchedule schedule(settings, t0, chains.size());
    uint64_t evaluations = 0;
    while (!chains.empty() && schedule.begin_round(evaluations)) {
        direct.before_round(schedule, evaluations);
        arena.execute([&] {
            tbb::parallel_for(tbb::blocked_range<size_t>(0, chains.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
                ScopedFtzDaz ftz;
                const TaskTimer timer(counters);
                PathCounters c;
                for (size_t k = r.begin(); k != r.end(); ++k) {
                    ChainRun& st = *chains[k];
                    const uint64_t end = schedule.round_end(st.budget, st.done);
                    PathSample last;
                    const SamplerProposal proposal{&tracer, &st.sampler, &c, &last};
                    auto splat = [&](const PathSample& s, double w) {
                        if (s.f > 0.0) film.add(s.pixel, s.L, w / s.f);
                    };
                    for (; st.done < end; ++st.done) {
                        const bool large = st.sampler.start_iteration();
                        const mlt::StepResult res = mlt::metropolis_step(
                            st.chain, target, proposal, splat, st.sampler, st.ws,
                            large ? mlt::MutationKind::large_step : mlt::MutationKind::small_step);
                        if (res.moved) st.sampler.accept();
                        else st.sampler.reject();
                        st.streaks.record(res.moved);
                        if (large) st.large.add(last.f);
                        st.invalid += last.invalid ? 1 : 0;
                        st.stats.record(res);
                    }
                }
                counters.add(c);
            });
        });
        if (!schedule.end_round(chains, [](const ChainRun& st) { return st.done; }, progress,
                                &evaluations, &cancelled))
            break;
    }
    direct.finish(cancelled, !chains.empty(), t0);
    const PtPassImage direct_image = direct_pass.develop();
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    // 5. normalisation: bootstrap + every large step, merged in chain order
    mlt::NormalisationAccumulator b_acc = boot_acc;
    mlt::KernelStats kstats;
    mlt::StreakTracker streaks;
    uint64_t mutations = 0, invalid = 0;
    auto states = std::make_shared<mlt::ChainStates>();
    states->path_sampler = settings.mlt_path_sampler;
    states->chains.reserve(chains.size());
    for (const auto& st : chains) {
        st->streaks.end();
        streaks.merge(st->streaks);
        states->chains.push_back(export_chain(*st));
        b_acc.merge(st->large);
        kstats.merge(st->stats);
        mutations += st->done;
        invalid += st->invalid;
    }
    const mlt::NormalisationEstimate b = b_acc.estimate();

    RenderResult res;
    res.width = W;
    res.height = H;
    mlt::develop_image(res, film, b.mean, mutations, direct_image);
    res.cancelled = cancelled;
    res.bootstrap_f.assign(boot_f.begin(), boot_f.end());
    res.mlt_states = std::move(states);
    res.mlt_start_states = std::move(start_states);

    RenderStats& st = res.stats;
    fill_frame_stats(st, counters, rate, secs);
    st.nan_samples = counters.invalid.load() + invalid + direct_image.nan_samples;
    st.threads = threads;
    st.integrator = settings.integrator;
    st.spp = settings.spp;
    st.seed = settings.seed;
    MltStats& m = st.mlt;
    mlt::fill_common_mlt_stats(m, settings, budget, b, b_boot, streaks, direct_pass.evaluations());
    m.chains = chains.size();
    m.mutations = mutations;
    m.mutations_per_pixel = double(mutations) / double(pixels);
    m.large_step_probability = settings.large_step_probability;
    const mlt::ChainStats& small = kstats[mlt::MutationKind::small_step];
    const mlt::ChainStats& large = kstats[mlt::MutationKind::large_step];
    m.small_steps = small.steps;
    m.large_steps = large.steps;
    m.acceptance_small = small.acceptance_rate();
    m.acceptance_large = large.acceptance_rate();
    m.imported_chains = initial ? chains.size() : 0;
    m.clamped_splats = film.clamped();
    m.path_evaluations = budget.pilot + direct_pass.evaluations() + budget.bootstrap + mutations;
    std::ostringstream os;
    kstats.write_json(os);
    m.kernel_stats_json = os.str();
    return res;
}

}  // namespace cmlt
