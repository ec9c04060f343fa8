// PSSMLT frame loop; see pssmlt_integrator.h for the estimator and its steps.
#include "integrators/pssmlt/pssmlt_integrator.h"

#include "integrators/mlt/chain_population.h"
#include "integrators/mlt/mlt_frame.h"
#include "integrators/path/path_tracer_impl.h"
#include "integrators/pssmlt/pssmlt_chain.h"
#include "scene/scene.h"

#include <memory>
#include <sstream>

namespace cmlt {

RenderResult render_pssmlt(const Scene& scene, const RenderSettings& given, const ProgressCallback& progress) {
    const RenderSettings settings = mlt::MltContext::resolve_paths(scene, given);  // mlt_paths auto
    using pssmlt::Chain;
    using pssmlt::make_sampler;
    using mlt::MltSampler;
    using mlt::PathSample;
    using mlt::RngDomain;

    // 1. pilot (in the context), direct pass, budget, film
    mlt::MltFrame frame(scene, settings);
    const mlt::PssmltTracer& tracer = frame.ctx.tracer;
    mlt::ChainPopulation<Chain> chains(frame, frame.budget.chains);

    // 2. bootstrap: N independent large-step samples, keyed (seed, bootstrap, i)
    chains.bootstrap([&](uint64_t i, PathCounters& c, bool& invalid) {
        MltSampler smp = make_sampler(settings, RngDomain::bootstrap, uint32_t(i));
        smp.start_iteration(true);
        const PathSample s = tracer.evaluate(smp, c);
        invalid = s.invalid;
        return s.f;
    });

    // 3. chain starts: the given states, re-evaluated in this frame's scene, or the
    //    resampled pool: replay the chosen sample, then rekey the sampler to the chain
    chains.start(
        [&](const mlt::ChainState& in, uint32_t k, PathCounters& c, bool& invalid) {
            MltSampler smp = make_sampler(settings, RngDomain::chain, k);
            smp.import_state(in.u);
            smp.begin_replay();
            const PathSample x = tracer.evaluate(smp, c);
            smp.end_replay();
            invalid = x.invalid;
            return std::make_unique<Chain>(std::move(smp), x);
        },
        [&](uint32_t i, uint32_t k, PathCounters& c) {
            MltSampler smp = make_sampler(settings, RngDomain::bootstrap, i);
            smp.start_iteration(true);
            const PathSample x = tracer.evaluate(smp, c);
            smp.accept();
            smp.set_key(RngDomain::chain, k);
            return std::make_unique<Chain>(std::move(smp), x);
        },
        pssmlt::export_chain);

    // 4. run the chains in rounds (frame_loop.h), expected-value splatting into the film
    chains.run(progress, [&] { return pssmlt::ChainTracer(tracer, frame.film); });

    // 5. normalisation (bootstrap + every large step), image and stats
    mlt::PopulationResult merged = chains.finish(pssmlt::export_chain);
    const mcmc::KernelStats kstats = merged.kernel;
    RenderResult res = frame.finish(std::move(merged));
    MltStats& m = res.stats.mlt;
    m.large_step_probability = settings.large_step_probability;
    const mcmc::ChainStats& small = kstats[mcmc::MutationKind::small_step];
    m.small_steps = small.steps;
    m.acceptance_small = small.acceptance_rate();
    std::ostringstream os;
    kstats.write_json(os);
    m.kernel_stats_json = os.str();
    return res;
}

}  // namespace cmlt
