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

#include <algorithm>
#include <array>
#include <cstdint>
#include <mutex>
#include <utility>
#include <vector>

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
        : m_settings(s), m_filter(tracer.filter()), m_splats(film), m_totals(totals), m_f(make_target(tracer, scene, s, &m_counters, &m_bundle)) {}
    ChainTracer(const ChainTracer&) = delete;
    ChainTracer& operator=(const ChainTracer&) = delete;

    /// Run blocks of `st` until it has spent `end` evaluations.
    void run(Chain& st, uint64_t end) {
        auto splat = splatter(st);
        while (st.evaluations < end) {
            // outer: independent large step, key (chain, id, n)
            const LargeStepProposal large{StateKey{RngDomain::chain, st.id, ++st.outer}};
            record_large(st, mcmc::metropolis_step(st.chain, m_f, large, splat, st.rng, st.ws,
                                                   mcmc::MutationKind::large_step));
            // inner chain
            for (int i = 0; i < m_settings.inner_length; ++i) {
                const Perturbation kind = choose_perturbation(st.rng.uniform(), st.chain.x);
                const PerturbationProposal prop = PerturbationProposal::make(
                    kind, m_settings.seed, m_settings.sigma_pixels, m_settings.sigma_primary, m_settings.width,
                    m_settings.height, st.rng);
                record_inner(st, kind, inner_step(m_settings.rule, st.chain, m_f, prop, splat, st.rng, st.ws));
            }
        }
    }

    /// Chains run in lockstep by run_group: one round of queries holds the bundles of
    /// this many chains (k = 2: 16 candidates, one full AVX-512 packet of camera rays).
    static constexpr size_t k_lockstep_chains = 8;

    /// Where chain `st` is on the film, as a key whose order keeps neighbours together
    /// (Morton order of its state's film position in cells of 4 × 4 pixels), for
    /// grouping chains in lockstep by image region.
    static uint64_t region(const Chain& st) {
        const Vec2 p = st.chain.x.sample.p_film;
        const auto cell = [](float v) { return v > 0.f ? uint32_t(std::min(v * 0.25f, 65535.f)) : 0u; };
        uint64_t key = 0;
        const uint32_t x = cell(p.x), y = cell(p.y);
        for (int b = 0; b < 16; ++b) key |= uint64_t((x >> b) & 1u) << (2 * b) | uint64_t((y >> b) & 1u) << (2 * b + 1);
        return key;
    }

    /// Run chains[0..n) in lockstep until chain i has spent ends[i] evaluations (README,
    /// "Packets and chains in lockstep"): each round every chain draws its next step's points (a
    /// large step's one, or an inner step's bundle of k), the target evaluates all of
    /// them together (one BundleEvaluator: their ray queries in common packets), then
    /// each chain finishes its step. A chain's numbers come from its own generator in the
    /// order run() draws them, and the points' values do not depend on how their queries
    /// are grouped (bundle_tracer.h), so every chain takes the same steps and makes the
    /// same splats as run() alone, bit for bit. Rules other than `bundle` (mtm's
    /// reference points depend on its candidates' values) run chain by chain.
    void run_group(Chain* const* chains, const uint64_t* ends, size_t n) {
        if (m_settings.rule != InnerRule::bundle || n < 2) {
            for (size_t i = 0; i < n; ++i) run(*chains[i], ends[i]);
            return;
        }
        // per chain: 0 = the block's outer step next, 1..m = inner step i, -1 = done
        m_phase.assign(n, 0);
        m_kind.resize(n);
        for (;;) {
            m_points.clear();
            for (size_t i = 0; i < n; ++i) {
                Chain& st = *chains[i];
                int& phase = m_phase[i];
                if (phase == 0 && st.evaluations >= ends[i]) phase = -1;
                if (phase < 0) continue;
                if (phase == 0) {
                    const LargeStepProposal large{StateKey{RngDomain::chain, st.id, ++st.outer}};
                    mcmc::metropolis_draw(st.chain, large, st.rng, st.ws);
                    m_points.push_back(&st.ws.y[0]);
                } else {
                    const Perturbation kind = choose_perturbation(st.rng.uniform(), st.chain.x);
                    m_kind[i] = kind;
                    const PerturbationProposal prop = PerturbationProposal::make(
                        kind, m_settings.seed, m_settings.sigma_pixels, m_settings.sigma_primary, m_settings.width,
                        m_settings.height, st.rng);
                    mcmc::bundle_draw(st.chain, prop, st.rng, st.ws);
                    for (size_t l = 0; l < st.ws.tries(); ++l) m_points.push_back(&st.ws.y[l]);
                }
            }
            if (m_points.empty()) break;
            m_f.prepare(m_points.data(), m_points.size());
            for (size_t i = 0; i < n; ++i) {
                Chain& st = *chains[i];
                int& phase = m_phase[i];
                if (phase < 0) continue;
                auto splat = splatter(st);
                if (phase == 0) {
                    const mcmc::StepResult res = mcmc::metropolis_finish(st.chain, m_f, LargeStepProposal{}, splat,
                                                                         st.rng, st.ws, mcmc::MutationKind::large_step);
                    record_large(st, res);
                } else {
                    const mcmc::StepResult ir = mcmc::bundle_finish(st.chain, m_f, splat, st.rng, st.ws);
                    record_inner(st, m_kind[i], ir);
                }
                phase = phase >= m_settings.inner_length ? 0 : phase + 1;
            }
        }
    }

    void flush(FrameCounters& counters) {
        m_splats.flush();
        counters.add(m_counters, 0, m_bundle.packets);
        const std::lock_guard<std::mutex> lock(m_totals.mutex);
        m_totals.sum.merge(m_bundle);
    }

private:
    /// The splat of chain `st`'s points: into its film layer, L / f* times the weight.
    struct Splatter {
        const PixelFilter& filter;
        SplatBuffer& film;
        Chain& st;
        void operator()(const State& s, double w) const {
            if (s.sample.f > 0.0) {
                film.add_filtered(filter, s.sample.p_film, s.sample.pixel, s.sample.L, w / s.sample.f, st.layer);
                st.record_splat(s.sample.L, s.sample.f, w, &s == &st.chain.x);
            }
        }
    };
    Splatter splatter(Chain& st) { return Splatter{m_filter, m_splats, st}; }
    static void record_large(Chain& st, const mcmc::StepResult& res) {
        const State& proposed = res.moved ? st.chain.x : st.ws.y[0];
        st.large.add(proposed.sample.f);
        st.invalid += proposed.sample.invalid ? 1 : 0;
        st.record(res);
    }
    static void record_inner(Chain& st, Perturbation kind, const mcmc::StepResult& ir) {
        st.perturbation[size_t(kind)].record(ir);
        st.invalid += ir.invalid_values;
        st.record(ir);
    }

    const CmltSettings& m_settings;
    const PixelFilter& m_filter;
    SplatBuffer m_splats;  ///< the frame's film, written through a buffer
    BundleTotals& m_totals;
    PathCounters m_counters;
    BundleCounters m_bundle;
    const Target m_f;
    std::vector<int> m_phase;                 ///< run_group: each chain's step in its block
    std::vector<Perturbation> m_kind;         ///< run_group: each chain's inner perturbation
    std::vector<const State*> m_points;       ///< run_group: the round's points
};

}  // namespace cmlt::coherent
