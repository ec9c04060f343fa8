#pragma once
/// \file The chain population of a Metropolis frame (pssmlt, cmlt): bootstrap, chain
/// starts, carried-over states, the chain rounds and the merged statistics. The
/// integrators differ only in what a chain is and how it steps; both run this.
///
///   1. bootstrap (`bootstrap`): N independent large-step samples, f* of each evaluated
///      in parallel (keyed (seed, bootstrap, i): the same points in pssmlt and cmlt), or
///      given (RenderSettings::mlt_bootstrap_f, the temporal driver's coupled starts);
///      b̂ = their mean, accumulated in index order (deterministic);
///   2. chain starts (`start`), either
///      * resampled from the bootstrap pool ∝ f* (mcmc::resample_start_indices with the
///        numbers of (seed, resample, 0): no start-up bias, no burn-in,
///        mcmc/normalisation.h); the integrator replays the chosen sample and re-keys it
///        to the chain, and the population checks that the replay gave the same f*;
///      * or, with RenderSettings::mlt_initial_states, the given states (the temporal
///        carry-over), one chain each, evaluated in this frame's scene;
///      the chain count is the setting (or the number of states), at most `max_chains`,
///      never the thread count; chain c takes its share of the chains' budget;
///   3. rounds (`run`, frame_loop.h's ChainSchedule): every chain runs to its round's
///      evaluation count in parallel tasks, one per-task tracer each (the integrator's
///      per-thread path work), the direct pass in slices between the rounds;
///   4. `finish`: b from the bootstrap and every chain's large steps, kernel statistics,
///      streaks, counts and the final states, merged in chain order (PopulationResult).
/// Chain c's numbers are keyed by (seed, c) and splats are summed order-independently
/// (film/splat_film.h), so the image is bit-identical for any number of threads.
#include "integrators/mlt/chain_state.h"
#include "integrators/mlt/mlt_frame.h"
#include "integrators/mlt/mlt_sampler.h"
#include "mcmc/chain_diagnostics.h"
#include "mcmc/normalisation.h"
#include "mcmc/step_stats.h"
#include "mcmc/workspace.h"
#include "util/error.h"

#include <algorithm>
#include <cstdint>
#include <memory>
#include <type_traits>
#include <vector>

namespace cmlt::mlt {

/// What every chain of a population keeps for the frame loop. An integrator's chain type
/// derives from it and adds its Markov chain (an mcmc::Chain named `chain`), its numbers
/// and its scratch.
struct ChainTally {
    uint64_t chain_id = 0;  ///< carried over from an imported state, else the chain's index
    uint64_t budget = 0;    ///< path evaluations the chain may spend
    uint64_t evaluations = 0, steps = 0;
    uint64_t invalid = 0;   ///< evaluations whose path was not finite
    int layer = 0;          ///< the splat film layer: the chain's error group (mlt_frame.h)
    mcmc::KernelStats stats;
    mcmc::NormalisationAccumulator large;  ///< f* of the large-step proposals
    mcmc::StreakTracker streaks;
    mcmc::ChainShare share;  ///< where its splat weight went (stuck-chain statistics)

    /// A splat of `weight` on `L` with target value `f` > 0; `current`: on the chain's
    /// current state (not a proposal).
    void record_splat(const Spectrum& L, double f, double weight, bool current) {
        share.add(weight * double(luminance(L)) / f, current);
    }

    /// Count one kernel step (after its splats).
    void record(const mcmc::StepResult& r) {
        evaluations += r.evaluations;
        ++steps;
        stats.record(r);
        streaks.record(r.moved);
        if (r.moved) share.end_stay();
    }
};

/// The given start states of a frame (nullptr when there are none), checked against the
/// path sampler.
inline const ChainStates* initial_states(const RenderSettings& s) {
    const ChainStates* initial = s.mlt_initial_states.get();
    if (initial && initial->chains.empty()) return nullptr;
    if (initial && initial->path_sampler != s.mlt_path_sampler)
        CMLT_THROW(SettingsError, "RenderSettings.mlt_initial_states: states of the '"
                                      << initial->path_sampler << "' path sampler cannot start '"
                                      << s.mlt_path_sampler << "' chains");
    return initial;
}

/// Does a chain tracer run groups of chains in lockstep (a member `run_group(Chain* const*,
/// const uint64_t* ends, size_t n)` and its group size `k_lockstep_chains`; coherent MLT)?
template <class Tracer, class = void>
struct has_run_group : std::false_type {};
template <class Tracer>
struct has_run_group<Tracer, std::void_t<decltype(Tracer::k_lockstep_chains)>> : std::true_type {};

/// The chains of one frame (see the file comment). `Chain` derives from ChainTally and
/// has a member `chain` (mcmc::Chain) whose `fx` is f* of its state.
template <class Chain>
class ChainPopulation {
public:
    /// At most `max_chains` chains (the budget's limit).
    ChainPopulation(MltFrame& frame, uint64_t max_chains)
        : m_frame(frame), m_initial(initial_states(frame.settings)),
          m_count(m_initial ? std::min<uint64_t>(m_initial->chains.size(), max_chains)
                            : std::min<uint64_t>(uint64_t(frame.settings.chains), max_chains)) {}

    size_t size() const { return m_chains.size(); }
    const Chain& operator[](size_t i) const { return *m_chains[i]; }

    /// 1. f* of bootstrap samples 0..N−1: `eval(i, PathCounters&, bool& invalid) -> double`,
    /// or RenderSettings::mlt_bootstrap_f if given (the temporal driver evaluated them
    /// already; it must hold N values), which is not evaluated again.
    template <class Eval>
    void bootstrap(Eval&& eval) {
        MltFrame& fr = m_frame;
        const uint64_t n = fr.budget.bootstrap;
        if (const auto& given = fr.settings.mlt_bootstrap_f) {
            if (given->size() != n)
                CMLT_THROW(SettingsError, "RenderSettings.mlt_bootstrap_f holds "
                                              << given->size() << " values, the frame's bootstrap has " << n
                                              << " samples");
            m_boot_f = *given;
        } else {
            m_boot_f.assign(n, 0.0);
            parallel_tasks(fr.arena, fr.counters, n, uint64_t(256), [&](const tbb::blocked_range<uint64_t>& r) {
                PathCounters c;
                uint64_t bad = 0;
                for (uint64_t i = r.begin(); i != r.end(); ++i) {
                    bool invalid = false;
                    m_boot_f[i] = eval(i, c, invalid);
                    bad += invalid ? 1 : 0;
                }
                fr.counters.add(c, bad);
            });
        }
        for (double f : m_boot_f) m_boot_acc.add(f);  // index order: deterministic
        m_b_boot = m_boot_acc.estimate();
    }

    /// 2. Start the chains: `import(const ChainState&, uint32_t chain, PathCounters&, bool&
    /// invalid)` from a given state, else `replay(uint32_t bootstrap_index, uint32_t chain,
    /// PathCounters&)` from a resampled bootstrap sample; both return a
    /// std::unique_ptr<Chain>. `export_chain(const Chain&) -> ChainState` records the
    /// start states.
    template <class Import, class Replay, class Export>
    void start(Import&& import, Replay&& replay, Export&& export_chain) {
        MltFrame& fr = m_frame;
        const uint64_t n = m_count, total = fr.budget.chains;
        const auto budget_of = [&](uint64_t k) { return total / n + (k < total % n ? 1 : 0); };
        if (total == 0 || n == 0) {
            // no chains (max_depth 1 with a direct pass)
        } else if (m_initial) {
            m_chains.resize(n);
            parallel_tasks(fr.arena, fr.counters, n, uint64_t(8), [&](const tbb::blocked_range<uint64_t>& r) {
                PathCounters c;
                uint64_t bad = 0;
                for (uint64_t k = r.begin(); k != r.end(); ++k) {
                    const ChainState& in = m_initial->chains[subsampled_state(k, n, m_initial->chains.size())];
                    bool invalid = false;
                    m_chains[k] = import(in, uint32_t(k), c, invalid);
                    bad += invalid ? 1 : 0;
                    m_chains[k]->chain_id = in.chain_id;
                    m_chains[k]->budget = budget_of(k);
                    m_chains[k]->layer = int(k % uint64_t(fr.film.layers()));
                }
                fr.counters.add(c, bad);
            });
        } else if (m_b_boot.nonzero > 0) {
            CounterRng rng(fr.settings.seed, RngDomain::resample, 0);
            const std::vector<size_t> pick = mcmc::resample_start_indices(m_boot_f, size_t(n), rng);
            const std::vector<int> layers = start_sample_groups(pick, fr.film.layers());
            m_chains.resize(n);
            parallel_tasks(fr.arena, fr.counters, n, uint64_t(8), [&](const tbb::blocked_range<uint64_t>& r) {
                PathCounters c;
                for (uint64_t k = r.begin(); k != r.end(); ++k) {
                    m_chains[k] = replay(uint32_t(pick[k]), uint32_t(k), c);
                    CMLT_CHECK_MSG(m_chains[k]->chain.fx == m_boot_f[pick[k]],
                                   fr.settings.integrator << ": replaying bootstrap sample " << pick[k]
                                                          << " gave a different path");
                    m_chains[k]->chain_id = k;
                    m_chains[k]->budget = budget_of(k);
                    m_chains[k]->layer = layers[k];
                }
                fr.counters.add(c);
            });
        }
        m_start_states = export_states(export_chain);
    }

    /// 3. Run the chains in rounds until the budget or the time is spent or `progress`
    /// stops the frame. `make_tracer()` gives each parallel task its tracer, with
    /// `run(Chain&, uint64_t end)` (step the chain until `end` evaluations) and
    /// `flush(FrameCounters&)` (add the task's counters).
    template <class MakeTracer>
    void run(const ProgressCallback& progress, MakeTracer&& make_tracer) {
        MltFrame& fr = m_frame;
        // no chain started (the bootstrap found no path the chains render, none was
        // carried): the direct pass renders the frame with the chains' evaluations too —
        // its own class of paths only. The chains' estimate of theirs is b times their
        // image, 0 with b = 0, and unbiased counting those zeros: a frame that rendered
        // the chains' paths wherever none started would count them P(b = 0) times too
        // often (test_mlt_paths.py, test_08).
        const bool none_started = m_chains.empty() && fr.budget.chains > 0 && fr.direct_pass.enabled();
        if (MltContext::chainless(fr.settings) || none_started) {  // the direct pass renders the frame
            m_target_reached = fr.direct.run_alone(progress, fr.t0, &m_cancelled, &m_direct_history,
                                                   none_started ? fr.direct_passes_without_chains() : 0);
            m_direct_alone = true;
            return;
        }
        ChainSchedule schedule(fr.settings, fr.t0, m_chains.size());
        uint64_t evaluations = 0;
        const std::pair<size_t, size_t> run = part_chains(fr.settings, m_chains.size());  // all, or a part's
        const int groups = fr.film.layers();
        if (schedule.targeted() && fr.settings.partial)
            CMLT_THROW(SettingsError, "RenderSettings.target_error: a part of a frame "
                                      "(RenderSettings.partial) cannot stop at a target error; "
                                      "the parts' film would not add up to the whole frame's");
        if (schedule.targeted() && groups < 3)
            CMLT_THROW(SettingsError, "RenderSettings.target_error: " << fr.settings.integrator
                                          << " needs error_groups >= 3 for its estimate");
        const uint64_t pixels = uint64_t(fr.settings.width) * uint64_t(fr.settings.height);
        if (schedule.targeted()) schedule.set_fraction(target_first_fraction(pixels, fr.budget.chains));
        while (!m_chains.empty() && schedule.begin_round(evaluations)) {
            fr.direct.before_round(schedule, evaluations);
            using Tracer = decltype(make_tracer());
            if constexpr (has_run_group<Tracer>::value) {
                // groups of chains in lockstep (cmlt_chain.h run_group), neighbours on the
                // film at the round's start (Tracer::region: their camera rays coherent);
                // the grouping decides only which queries share packets, never a chain's
                // steps, so the image does not depend on it
                const size_t g = Tracer::k_lockstep_chains, count = run.second - run.first;
                m_order.resize(count);
                m_region.resize(count);
                for (size_t i = 0; i < count; ++i) {
                    m_order[i] = uint32_t(run.first + i);
                    m_region[i] = Tracer::region(*m_chains[run.first + i]);
                }
                std::sort(m_order.begin(), m_order.end(), [&](uint32_t a, uint32_t b) {
                    const uint64_t ra = m_region[a - run.first], rb = m_region[b - run.first];
                    return ra != rb ? ra < rb : a < b;
                });
                parallel_tasks(fr.arena, fr.counters, (count + g - 1) / g, size_t(1), [&](const tbb::blocked_range<size_t>& r) {
                    auto tracer = make_tracer();
                    Chain* group[Tracer::k_lockstep_chains];
                    uint64_t ends[Tracer::k_lockstep_chains];
                    for (size_t q = r.begin(); q != r.end(); ++q) {
                        const size_t k0 = q * g, n = std::min(g, count - k0);
                        for (size_t i = 0; i < n; ++i) {
                            group[i] = m_chains[m_order[k0 + i]].get();
                            ends[i] = schedule.round_end(group[i]->budget, group[i]->evaluations);
                        }
                        tracer.run_group(group, ends, n);
                    }
                    tracer.flush(fr.counters);
                });
            } else {
                parallel_tasks(fr.arena, fr.counters, run.second - run.first, size_t(1), [&](const tbb::blocked_range<size_t>& r) {
                    auto tracer = make_tracer();
                    for (size_t k = run.first + r.begin(); k != run.first + r.end(); ++k) {
                        Chain& chain = *m_chains[k];
                        tracer.run(chain, schedule.round_end(chain.budget, chain.evaluations));
                    }
                    tracer.flush(fr.counters);
                });
            }
            if (schedule.targeted()) {  // the estimate from the chain groups (error_target.h)
                uint64_t chain_evals = 0;
                for (const auto& c : m_chains) chain_evals += c->evaluations;
                const double work =
                    double(fr.budget.pilot + fr.direct_pass.evaluations() + fr.budget.bootstrap + chain_evals) /
                    double(pixels);
                const ErrorValue e = estimate_groups(fr.film, group_steps(), b_so_far(), fr.direct_pass.develop());
                if (target_round(m_target, schedule, e, work, chain_evals, fr.budget.chains, groups)) {
                    m_target_reached = true;
                    break;
                }
            }
            if (!schedule.end_round(m_chains, [](const Chain& c) { return c.evaluations; }, progress, &evaluations,
                                    &m_cancelled))
                break;
        }
        fr.direct.finish(m_cancelled || m_target_reached, !m_chains.empty(), fr.t0);
    }

    /// 4. Merge the chains in chain order; `export_chain` gives their final states.
    template <class Export>
    PopulationResult finish(Export&& export_chain) {
        PopulationResult out;
        mcmc::NormalisationAccumulator b = m_boot_acc;
        for (const auto& c : m_chains) {
            c->streaks.end();
            c->share.end_stay();
            out.shares.add(c->share, c->streaks.max_streak);
            out.streaks.merge(c->streaks);
            b.merge(c->large);
            out.kernel.merge(c->stats);
            out.steps += c->steps;
            out.evaluations += c->evaluations;
            out.invalid += c->invalid;
        }
        out.b = b.estimate();
        out.b_bootstrap = m_b_boot;
        out.bootstrap_f = std::move(m_boot_f);
        out.chains = m_chains.size();
        out.imported = m_initial != nullptr;
        out.cancelled = m_cancelled;
        out.group_steps = group_steps();
        out.target_reached = m_target_reached;
        out.direct_alone = m_direct_alone;
        out.error_history = m_direct_alone ? std::move(m_direct_history) : m_target.take_history();
        out.states = export_states(export_chain);
        out.start_states = std::move(m_start_states);
        if (m_frame.settings.partial) {
            // a part of the frame: the bootstrap's accumulator, then its chains' in order
            const auto run = part_chains(m_frame.settings, m_chains.size());
            out.part_norms.push_back(m_boot_acc);
            for (size_t k = run.first; k < run.second; ++k) out.part_norms.push_back(m_chains[k]->large);
        }
        return out;
    }

private:
    /// Steps per error group (the chains' film layers).
    std::vector<double> group_steps() const {
        std::vector<double> out(size_t(m_frame.film.layers()), 0.0);
        for (const auto& c : m_chains) out[size_t(c->layer)] += double(c->steps);
        return out;
    }
    /// b so far: the bootstrap and every chain's large steps.
    mcmc::NormalisationEstimate b_so_far() const {
        mcmc::NormalisationAccumulator acc = m_boot_acc;
        for (const auto& c : m_chains) acc.merge(c->large);
        return acc.estimate();
    }

    template <class Export>
    std::shared_ptr<ChainStates> export_states(Export& export_chain) const {
        auto out = std::make_shared<ChainStates>();
        out->path_sampler = m_frame.settings.mlt_path_sampler;
        out->chains.reserve(m_chains.size());
        for (const auto& c : m_chains) out->chains.push_back(export_chain(*c));
        return out;
    }

    MltFrame& m_frame;
    const ChainStates* m_initial;
    uint64_t m_count;  ///< chains to start
    std::vector<std::unique_ptr<Chain>> m_chains;
    std::vector<uint32_t> m_order;   ///< run: the chains in lockstep groups' order
    std::vector<uint64_t> m_region;  ///< run: each chain's film region at the round's start
    std::vector<double> m_boot_f;
    mcmc::NormalisationAccumulator m_boot_acc;
    mcmc::NormalisationEstimate m_b_boot;
    std::shared_ptr<ChainStates> m_start_states;
    bool m_cancelled = false;
    ErrorTarget m_target{m_frame.settings.target_error, 0.0};
    bool m_target_reached = false;
    std::vector<std::array<double, 4>> m_direct_history;  ///< a chainless frame's target estimates
    bool m_direct_alone = false;  ///< the direct pass rendered the frame (run_alone)
};

}  // namespace cmlt::mlt
