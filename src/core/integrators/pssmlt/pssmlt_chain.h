#pragma once
/// \file One PSSMLT chain and its per-thread path work (the tracer of Tungsten's split):
/// the chain's MltSampler (primary samples with lazy mutation, mlt_sampler.h), its
/// Markov chain over path samples, and the steps — a large step with probability
/// `large_step_probability`, else a small wrapped-Gaussian step of σ — taken by
/// mcmc::metropolis_step with expected-value splats into the frame's SplatFilm.
#include "film/splat_film.h"
#include "integrators/common/frame_loop.h"
#include "integrators/common/render_settings.h"
#include "integrators/mlt/chain_population.h"
#include "integrators/mlt/chain_state.h"
#include "integrators/mlt/mlt_sampler.h"
#include "integrators/mlt/pssmlt_tracer.h"
#include "integrators/mlt/technique.h"
#include "mcmc/kernels.h"
#include "mcmc/workspace.h"

#include <cstdint>
#include <utility>

namespace cmlt::pssmlt {

using mlt::MltSampler;
using mlt::PathSample;

/// The numbers of a chain (or a bootstrap sample) keyed (seed, domain, id). With the
/// bdpt path sampler the technique samples change at large steps only (multiplexed MLT,
/// mlt_sampler.h).
inline MltSampler make_sampler(const RenderSettings& s, RngDomain domain, uint32_t id) {
    MltSampler smp(s.seed, s.sigma, s.large_step_probability, domain, id);
    if (s.mlt_path_sampler == "bdpt")
        smp.freeze_in_small_steps(MltSampler::connection, mlt::k_technique_dimensions * MltSampler::k_slots_per_dimension);
    return smp;
}

/// One Markov chain and everything it accumulates.
struct Chain : mlt::ChainTally {
    Chain(MltSampler s, const PathSample& x) : sampler(std::move(s)), ws(1, PathSample{}) {
        chain.x = x;
        chain.fx = x.f;
    }
    MltSampler sampler;
    mcmc::Chain<PathSample> chain;
    mcmc::Workspace<PathSample> ws;
};

/// The chain's current state as a ChainState (chain_state.h).
inline mlt::ChainState export_chain(const Chain& c) {
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

/// The chain steps of one parallel task (ChainPopulation::run).
class ChainTracer {
public:
    ChainTracer(const mlt::PssmltTracer& tracer, SplatFilm& film) : m_tracer(tracer), m_splats(film) {}

    /// Step `st` until it has spent `end` evaluations.
    void run(Chain& st, uint64_t end) {
        PathSample last;
        const SamplerProposal proposal{&m_tracer, &st.sampler, &m_counters, &last};
        const auto target = [](const PathSample& s) { return s.f; };
        auto splat = [&](const PathSample& s, double w) {
            if (s.f > 0.0) {
                m_splats.add_filtered(m_tracer.filter(), s.p_film, s.pixel, s.L, w / s.f, st.layer);
                st.record_splat(s.L, s.f, w, &s == &st.chain.x);
            }
        };
        while (st.evaluations < end) {
            const bool large = st.sampler.start_iteration();
            const mcmc::StepResult res =
                mcmc::metropolis_step(st.chain, target, proposal, splat, st.sampler, st.ws,
                                      large ? mcmc::MutationKind::large_step : mcmc::MutationKind::small_step);
            if (res.moved) st.sampler.accept();
            else st.sampler.reject();
            if (large) st.large.add(last.f);
            st.invalid += last.invalid ? 1 : 0;
            st.record(res);
        }
    }
    /// The task's counters and its splats (into the frame's film).
    void flush(FrameCounters& counters) {
        counters.add(m_counters);
        m_splats.flush();
    }

private:
    const mlt::PssmltTracer& m_tracer;
    SplatBuffer m_splats;  ///< the frame's film, written through a buffer
    PathCounters m_counters;
};

}  // namespace cmlt::pssmlt
