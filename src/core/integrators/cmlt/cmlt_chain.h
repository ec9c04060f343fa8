#pragma once
/// \file One coherent-MLT chain and its per-thread path work (the tracer of Tungsten's
/// split). A chain runs blocks until its budget of path evaluations is spent:
///   1. outer step: a large step (a new key: an independent uniform point), accepted by
///      Metropolis–Hastings with expected-value splats (mcmc::metropolis_step);
///   2. inner chain: `inner_length` (m) steps of `tries` (k) candidates each, drawn as one
///      bundle by a perturbation (perturbations.h) and taken by the inner rule
///      (inner_rule.h); the target evaluates each bundle's candidates together
///      (cmlt_target.h, bundle_tracer.h).
/// Every step splats total weight 1 into the frame's SplatFilm (L / f* times the weight).
#include "film/splat_film.h"
#include "integrators/cmlt/bundle_tracer.h"
#include "integrators/cmlt/cmlt_settings.h"
#include "integrators/cmlt/cmlt_state.h"
#include "integrators/cmlt/cmlt_target.h"
#include "integrators/cmlt/inner_rule.h"
#include "integrators/cmlt/perturbations.h"
#include "integrators/common/frame_loop.h"
#include "integrators/mlt/chain_population.h"
#include "integrators/mlt/pssmlt_tracer.h"
#include "mcmc/kernels.h"
#include "mcmc/step_stats.h"
#include "mcmc/workspace.h"
#include "scene/scene.h"

#include <array>
#include <cstdint>
#include <mutex>
#include <utility>

namespace cmlt::coherent {

/// One chain: its kernel numbers, its Markov chain and scratch, its statistics.
struct Chain : mlt::ChainTally {
    Chain(uint64_t seed, uint32_t id, size_t tries, State x, double fx)
        : rng(seed, RngDomain::chain, id), id(id), ws(tries, x) {
        chain.x = std::move(x);
        chain.fx = fx;
    }
    CounterRng rng;  ///< kernel numbers (perturbation choice, offsets, acceptance)
    uint32_t id;     ///< the chain's index: keys its numbers
    mcmc::Workspace<State> ws;
    mcmc::Chain<State> chain;
    uint64_t outer = 0;  ///< outer steps taken (keys the large steps)
    std::array<mcmc::ChainStats, k_perturbation_count> perturbation{};
};

/// The target of one task: f* of points through `tracer`, rays counted in `counters`,
/// bundle tracing in `bundle` (nullptr: not counted).
inline Target make_target(const mlt::PssmltTracer& tracer, const Scene& scene, const CmltSettings& s,
                          PathCounters* counters, BundleCounters* bundle) {
    Target f;
    f.tracer = &tracer;
    f.scene = &scene;
    f.seed = s.seed;
    f.counters = counters;
    f.packets = s.packets;
    f.max_width = s.max_width;
    f.bundle = bundle;
    return f;
}

/// Bundle-tracing counters of a frame, merged over its tasks.
struct BundleTotals {
    BundleCounters sum;
    std::mutex mutex;
};

/// The chain blocks of one parallel task (mlt::ChainPopulation::run; see the file
/// comment). Holds the task's counters; not copyable (its target points at them).
class ChainTracer {
public:
    ChainTracer(const mlt::PssmltTracer& tracer, const Scene& scene, const CmltSettings& s, SplatFilm& film,
                BundleTotals& totals)
        : m_settings(s), m_filter(tracer.filter()), m_film(film), m_totals(totals), m_f(make_target(tracer, scene, s, &m_counters, &m_bundle)) {}
    ChainTracer(const ChainTracer&) = delete;
    ChainTracer& operator=(const ChainTracer&) = delete;

    /// Run blocks of `st` until it has spent `end` evaluations.
    void run(Chain& st, uint64_t end) {
        auto splat = [&](const State& s, double w) {
            if (s.sample.f > 0.0) {
                m_film.add_filtered(m_filter, s.sample.p_film, s.sample.pixel, s.sample.L, w / s.sample.f,
                                    st.layer);
                st.record_splat(s.sample.L, s.sample.f, w, &s == &st.chain.x);
            }
        };
        while (st.evaluations < end) {
            // outer: independent large step, key (chain, id, n)
            const LargeStepProposal large{StateKey{RngDomain::chain, st.id, ++st.outer}};
            const mcmc::StepResult res =
                mcmc::metropolis_step(st.chain, m_f, large, splat, st.rng, st.ws, mcmc::MutationKind::large_step);
            const State& proposed = res.moved ? st.chain.x : st.ws.y[0];
            st.large.add(proposed.sample.f);
            st.invalid += proposed.sample.invalid ? 1 : 0;
            st.record(res);
            // inner chain
            for (int i = 0; i < m_settings.inner_length; ++i) {
                const Perturbation kind = choose_perturbation(st.rng.uniform(), st.chain.x);
                const PerturbationProposal prop = PerturbationProposal::make(
                    kind, m_settings.seed, m_settings.sigma_pixels, m_settings.sigma_primary, m_settings.width,
                    m_settings.height, st.rng);
                const mcmc::StepResult ir = inner_step(m_settings.rule, st.chain, m_f, prop, splat, st.rng, st.ws);
                st.perturbation[size_t(kind)].record(ir);
                st.invalid += ir.invalid_values;
                st.record(ir);
            }
        }
    }

    void flush(FrameCounters& counters) {
        counters.add(m_counters, 0, m_bundle.packets);
        const std::lock_guard<std::mutex> lock(m_totals.mutex);
        m_totals.sum.merge(m_bundle);
    }

private:
    const CmltSettings& m_settings;
    const PixelFilter& m_filter;
    SplatFilm& m_film;
    BundleTotals& m_totals;
    PathCounters m_counters;
    BundleCounters m_bundle;
    const Target m_f;
};

}  // namespace cmlt::coherent
