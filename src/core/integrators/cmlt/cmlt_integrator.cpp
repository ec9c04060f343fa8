// Coherent MLT frame loop; see cmlt_integrator.h (estimator) and cmlt_state.h (state,
// perturbations, packets).
#include "integrators/cmlt/cmlt_integrator.h"

#include "cameras/camera.h"
#include "integrators/bdpt/bdpt_tracer.h"
#include "integrators/cmlt/cmlt_state.h"
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
#include <array>
#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <sstream>

namespace cmlt {

namespace {

using coherent::LargeStepProposal;
using coherent::Perturbation;
using coherent::PerturbationProposal;
using coherent::State;
using coherent::StateKey;
using mlt::RngDomain;

mlt::InnerRule parse_rule(const std::string& name) {
    if (name == "seed") return mlt::InnerRule::seed;
    if (name == "mtm") return mlt::InnerRule::mtm;
    return mlt::InnerRule::bundle;
}

struct ChainState {
    ChainState(uint64_t seed, uint32_t id, size_t tries, State x, double fx)
        : rng(seed, RngDomain::chain, id), id(id), ws(tries, x) {
        chain.x = std::move(x);
        chain.fx = fx;
    }
    mlt::CounterRng rng;  ///< kernel numbers (perturbation choice, offsets, acceptance)
    uint32_t id;
    mlt::Workspace<State> ws;
    mlt::Chain<State> chain;
    uint64_t outer = 0;                 ///< outer steps taken (keys the large steps)
    uint64_t budget = 0, evaluations = 0, steps = 0;
    mlt::KernelStats stats;
    std::array<mlt::ChainStats, coherent::k_perturbation_count> perturbation{};
    mlt::NormalisationAccumulator large;
    mlt::StreakTracker streaks;
    uint64_t invalid = 0;
};

}  // namespace

RenderResult render_cmlt(const Scene& scene, const RenderSettings& settings, const ProgressCallback& progress) {
    const int W = settings.width, H = settings.height;
    const uint64_t pixels = uint64_t(W) * uint64_t(H);
    const int threads = settings.threads > 0 ? settings.threads : tbb::info::default_concurrency();
    tbb::task_arena arena(threads);
    FrameCounters counters;
    const CycleRate rate;
    const auto t0 = std::chrono::steady_clock::now();

    // 1. pilot (in the context) and direct pass
    PathCounters pilot_counters;
    const mlt::MltContext ctx(scene, settings, pilot_counters);
    counters.add(pilot_counters);
    // path sampler: multiplexed BDPT (default; t = 1 paths take the caustic perturbation)
    // or the path tracer (every path takes the lens perturbation)
    const mlt::PssmltTracer& tracer = ctx.tracer;
    mlt::DirectPass direct_pass(scene, settings);

    const uint64_t seed = settings.seed;
    const size_t k = size_t(settings.tries);
    const int m = settings.inner_length;
    const mlt::InnerRule rule = parse_rule(settings.inner);
    const double sigma_pixels = settings.sigma * double(std::max(W, H));
    const double sigma_primary = settings.sigma;
    const int max_width = Accel::max_packet_width();
    const double small_step_probability = coherent::k_small_step_probability;

    const mlt::FrameBudget budget = mlt::FrameBudget::plan(settings);
    const uint64_t n_mut = budget.chains;
    // a chain's block (outer step + inner chain) costs about 1 + m·k evaluations: no more
    // chains than blocks fit in the budget
    const uint64_t block = 1 + uint64_t(m) * uint64_t(k);
    const mlt::ChainStates* initial = settings.mlt_initial_states.get();
    if (initial && initial->chains.empty()) initial = nullptr;
    if (initial && initial->path_sampler != settings.mlt_path_sampler)
        CMLT_THROW(SettingsError, "RenderSettings.mlt_initial_states: states of the '"
                                      << initial->path_sampler << "' path sampler cannot start '"
                                      << settings.mlt_path_sampler << "' chains");
    const uint64_t max_chains = std::max<uint64_t>(1, n_mut / block);
    const uint64_t n_chains = initial ? std::min<uint64_t>(initial->chains.size(), max_chains)
                                      : std::min<uint64_t>(uint64_t(settings.chains), max_chains);
    mlt::SplatFilm film(W, H);
    mlt::DirectSchedule direct{direct_pass, settings, arena, counters};

    auto make_target = [&](PathCounters* c, coherent::BundleCounters* bundle) {
        coherent::Target f;
        f.tracer = &tracer;
        f.scene = &scene;
        f.seed = seed;
        f.counters = c;
        f.packets = settings.packets;
        f.max_width = max_width;
        f.bundle = bundle;
        return f;
    };
    // bundle tracing stats of the chain rounds, merged per task
    coherent::BundleCounters bundle_stats;
    std::mutex bundle_mutex;

    // 2. bootstrap: the points of PSSMLT's bootstrap, keys (bootstrap, i, 1)
    const std::vector<double> boot_f =
        mlt::bootstrap_values(settings, arena, budget.bootstrap, counters, [&](uint64_t i, PathCounters& c, bool& invalid) {
            const coherent::Target f = make_target(&c, nullptr);
            State s;
            s.key = StateKey{RngDomain::bootstrap, uint32_t(i), 1};
            const double v = f(s);
            invalid = s.sample.invalid;
            return v;
        });
    mlt::NormalisationAccumulator boot_acc;
    for (double v : boot_f) boot_acc.add(v);
    const mlt::NormalisationEstimate b_boot = boot_acc.estimate();

    // 3. chain starts: resample the pool ∝ f* (same numbers as pssmlt), or the given
    //    states (temporal carry-over), evaluated in this frame's scene
    std::vector<std::unique_ptr<ChainState>> chains;
    std::vector<uint64_t> chain_ids;
    if (initial && n_mut > 0) {
        chains.resize(n_chains);
        chain_ids.resize(n_chains);
        arena.execute([&] {
            tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n_chains, 8), [&](const tbb::blocked_range<uint64_t>& r) {
                ScopedFtzDaz ftz;
                const TaskTimer timer(counters);
                PathCounters c;
                uint64_t bad = 0;
                const coherent::Target f = make_target(&c, nullptr);
                for (uint64_t ci = r.begin(); ci != r.end(); ++ci) {
                    const mlt::ChainState& in =
                        initial->chains[mlt::subsampled_state(ci, n_chains, initial->chains.size())];
                    State x = coherent::import_state(in, StateKey{RngDomain::chain, uint32_t(ci), 0});
                    const double fx = f(x);
                    bad += x.sample.invalid ? 1 : 0;
                    chains[ci] = std::make_unique<ChainState>(seed, uint32_t(ci), k, std::move(x), fx);
                    chains[ci]->budget = n_mut / n_chains + (ci < n_mut % n_chains ? 1 : 0);
                    chain_ids[ci] = in.chain_id;
                }
                counters.add(c, bad);
            });
        });
    } else if (b_boot.nonzero > 0 && n_mut > 0) {
        mlt::CounterRng rng(seed, RngDomain::resample, 0);
        const std::vector<size_t> start = mlt::resample_start_indices(boot_f, size_t(n_chains), rng);
        chains.resize(n_chains);
        arena.execute([&] {
            tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n_chains, 8), [&](const tbb::blocked_range<uint64_t>& r) {
                ScopedFtzDaz ftz;
                const TaskTimer timer(counters);
                PathCounters c;
                const coherent::Target f = make_target(&c, nullptr);
                for (uint64_t ci = r.begin(); ci != r.end(); ++ci) {
                    State x0;
                    x0.key = StateKey{RngDomain::bootstrap, uint32_t(start[ci]), 1};
                    const double f0 = f(x0);
                    CMLT_CHECK_MSG(f0 == boot_f[start[ci]],
                                   "cmlt: replaying bootstrap sample " << start[ci] << " gave a different path");
                    // Re-key to the chain: the coordinates the path read become overrides
                    // (as floats, as an exported state holds them), the rest come from key
                    // (chain, ci, 0). A start carried into the next frame is then the same
                    // point bit for bit, unread coordinates included, so with stored seeds
                    // a static scene replays the chain exactly (temporal/carry.h).
                    State x = coherent::import_state(coherent::export_state(x0, seed, ci),
                                                     StateKey{RngDomain::chain, uint32_t(ci), 0});
                    const double fx = f(x);
                    CMLT_CHECK_MSG(fx == f0, "cmlt: re-keying bootstrap sample " << start[ci] << " changed its path");
                    chains[ci] = std::make_unique<ChainState>(seed, uint32_t(ci), k, std::move(x), fx);
                    chains[ci]->budget = n_mut / n_chains + (ci < n_mut % n_chains ? 1 : 0);
                }
                counters.add(c);
            });
        });
        chain_ids.resize(n_chains);
        for (uint64_t ci = 0; ci < n_chains; ++ci) chain_ids[ci] = ci;
    }
    const auto export_states = [&] {
        auto out = std::make_shared<mlt::ChainStates>();
        out->path_sampler = settings.mlt_path_sampler;
        out->chains.reserve(chains.size());
        for (size_t ci = 0; ci < chains.size(); ++ci)
            out->chains.push_back(coherent::export_state(chains[ci]->chain.x, seed, chain_ids[ci]));
        return out;
    };
    std::shared_ptr<mlt::ChainStates> start_states = export_states();

    // 4. run the chains in rounds: outer large step, then m inner bundle steps
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
                coherent::BundleCounters bc;
                const coherent::Target f = make_target(&c, &bc);
                for (size_t ci = r.begin(); ci != r.end(); ++ci) {
                    ChainState& st = *chains[ci];
                    const uint64_t end = schedule.round_end(st.budget, st.evaluations);
                    auto splat = [&](const State& s, double w) {
                        if (s.sample.f > 0.0) film.add(s.sample.pixel, s.sample.L, w / s.sample.f);
                    };
                    auto record = [&](const mlt::StepResult& res) {
                        st.evaluations += res.evaluations;
                        ++st.steps;
                        st.stats.record(res);
                        st.streaks.record(res.moved);
                    };
                    while (st.evaluations < end) {
                        // outer: independent large step, key (chain, id, n)
                        const LargeStepProposal large{StateKey{RngDomain::chain, st.id, ++st.outer}};
                        const mlt::StepResult res =
                            mlt::metropolis_step(st.chain, f, large, splat, st.rng, st.ws, mlt::MutationKind::large_step);
                        const State& proposed = res.moved ? st.chain.x : st.ws.y[0];
                        st.large.add(proposed.sample.f);
                        st.invalid += proposed.sample.invalid ? 1 : 0;
                        record(res);
                        // inner chain
                        for (int i = 0; i < m; ++i) {
                            Perturbation kind = Perturbation::lens;
                            const double u_kind = st.rng.uniform();
                            if (u_kind < coherent::k_pixel_move_probability)
                                kind = Perturbation::pixel_move;
                            else if (u_kind < coherent::k_pixel_move_probability + small_step_probability)
                                kind = Perturbation::small_step;
                            else if (coherent::light_traced(st.chain.x.sample))
                                kind = Perturbation::caustic;
                            const PerturbationProposal prop =
                                PerturbationProposal::make(kind, seed, sigma_pixels, sigma_primary, W, H, st.rng);
                            const mlt::StepResult ir = mlt::inner_step(rule, st.chain, f, prop, splat, st.rng, st.ws);
                            st.perturbation[size_t(kind)].record(ir);
                            st.invalid += ir.invalid_values;
                            record(ir);
                        }
                    }
                }
                counters.add(c, 0, bc.packets);
                const std::lock_guard<std::mutex> lock(bundle_mutex);
                bundle_stats.merge(bc);
            });
        });
        if (!schedule.end_round(chains, [](const ChainState& st) { return st.evaluations; }, progress,
                                &evaluations, &cancelled))
            break;
    }
    direct.finish(cancelled, !chains.empty(), t0);
    const PtPassImage direct_image = direct_pass.develop();
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    // 5. normalisation and stats, merged in chain order
    mlt::NormalisationAccumulator b_acc = boot_acc;
    mlt::KernelStats kstats;
    mlt::StreakTracker streaks;
    std::array<mlt::ChainStats, coherent::k_perturbation_count> pstats{};
    uint64_t steps = 0, invalid = 0;
    evaluations = 0;
    for (const auto& st : chains) {
        st->streaks.end();
        streaks.merge(st->streaks);
        b_acc.merge(st->large);
        kstats.merge(st->stats);
        for (size_t i = 0; i < pstats.size(); ++i) pstats[i].merge(st->perturbation[i]);
        steps += st->steps;
        evaluations += st->evaluations;
        invalid += st->invalid;
    }
    const mlt::NormalisationEstimate b = b_acc.estimate();

    RenderResult res;
    res.width = W;
    res.height = H;
    mlt::develop_image(res, film, b.mean, steps, direct_image);
    res.cancelled = cancelled;
    res.bootstrap_f.assign(boot_f.begin(), boot_f.end());
    res.mlt_states = export_states();
    res.mlt_start_states = std::move(start_states);

    RenderStats& st = res.stats;
    fill_frame_stats(st, counters, rate, secs);
    st.nan_samples = counters.invalid.load() + invalid + direct_image.nan_samples;
    st.threads = threads;
    st.integrator = settings.integrator;
    st.spp = settings.spp;
    st.seed = settings.seed;
    MltStats& ms = st.mlt;
    mlt::fill_common_mlt_stats(ms, settings, budget, b, b_boot, streaks, direct_pass.evaluations());
    ms.chains = chains.size();
    ms.mutations = steps;
    ms.mutations_per_pixel = double(steps) / double(pixels);
    ms.large_step_probability = 0.0;
    const mlt::ChainStats& large = kstats[mlt::MutationKind::large_step];
    mlt::ChainStats inner;
    for (size_t i = 0; i < pstats.size(); ++i) inner.merge(pstats[i]);
    ms.small_steps = inner.steps;
    ms.large_steps = large.steps;
    ms.acceptance_small = inner.acceptance_rate();
    ms.acceptance_large = large.acceptance_rate();
    ms.clamped_splats = film.clamped();
    ms.tries = settings.tries;
    ms.inner_length = settings.inner_length;
    ms.inner = settings.inner;
    ms.packets = settings.packets;
    ms.packet_width = settings.packets ? max_width : 1;
    ms.packet_queries = counters.packets.load();
    ms.packet_rays = bundle_stats.packet_rays;
    ms.packet_shadow_rays = bundle_stats.packet_shadow_rays;
    ms.bundle_rays = bundle_stats.bundle_rays;
    ms.bundle_busy_s = double(bundle_stats.busy_ticks) / rate.per_second();
    ms.bundle_trace_s = std::min(ms.bundle_busy_s, double(bundle_stats.trace_ticks) / rate.per_second());
    ms.imported_chains = initial ? chains.size() : 0;
    ms.path_evaluations = budget.pilot + direct_pass.evaluations() + budget.bootstrap + evaluations;
    // kernel stats by mutation name, then the perturbations (acceptance per type)
    std::ostringstream os;
    kstats.write_json(os);
    std::string json = os.str();
    json.pop_back();  // '}'
    bool first = json.size() <= 1;
    std::ostringstream ps;
    for (size_t i = 0; i < pstats.size(); ++i) {
        const mlt::ChainStats& s = pstats[i];
        if (s.steps == 0) continue;
        ps << (first ? "" : ", ") << '"' << coherent::perturbation_name(Perturbation(i)) << "\": {\"steps\": "
           << s.steps << ", \"moved\": " << s.moved << ", \"acceptance_rate\": " << s.acceptance_rate()
           << ", \"mean_acceptance\": " << s.mean_acceptance() << ", \"evaluations\": " << s.evaluations
           << ", \"zero_values\": " << s.zero_values << ", \"invalid_values\": " << s.invalid_values
           << ", \"splats\": " << s.splats << '}';
        first = false;
    }
    ms.kernel_stats_json = json + ps.str() + "}";
    return res;
}

}  // namespace cmlt
