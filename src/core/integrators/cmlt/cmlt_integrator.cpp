// Coherent MLT frame loop; see cmlt_integrator.h (estimator) and cmlt_chain.h (one chain).
#include "integrators/cmlt/cmlt_integrator.h"

#include "integrators/cmlt/cmlt_chain.h"
#include "integrators/mlt/chain_population.h"
#include "integrators/mlt/mlt_frame.h"
#include "integrators/path/path_tracer_impl.h"
#include "scene/scene.h"

#include <algorithm>
#include <array>
#include <memory>
#include <sstream>
#include <string>

namespace cmlt {

namespace {

using coherent::Chain;
using coherent::State;
using coherent::StateKey;
using mlt::RngDomain;

/// The kernel statistics by mutation name, then the perturbations (acceptance per type).
std::string kernel_stats_json(const mcmc::KernelStats& kstats,
                              const std::array<mcmc::ChainStats, coherent::k_perturbation_count>& pstats) {
    std::ostringstream os;
    kstats.write_json(os);
    std::string json = os.str();
    json.pop_back();  // '}'
    bool first = json.size() <= 1;
    std::ostringstream ps;
    for (size_t i = 0; i < pstats.size(); ++i) {
        const mcmc::ChainStats& s = pstats[i];
        if (s.steps == 0) continue;
        ps << (first ? "" : ", ") << '"' << coherent::perturbation_name(coherent::Perturbation(i))
           << "\": {\"steps\": " << s.steps << ", \"moved\": " << s.moved
           << ", \"acceptance_rate\": " << s.acceptance_rate() << ", \"mean_acceptance\": " << s.mean_acceptance()
           << ", \"evaluations\": " << s.evaluations << ", \"zero_values\": " << s.zero_values
           << ", \"invalid_values\": " << s.invalid_values << ", \"splats\": " << s.splats << '}';
        first = false;
    }
    return json + ps.str() + "}";
}

}  // namespace

RenderResult render_cmlt(const Scene& scene, const RenderSettings& given, const ProgressCallback& progress) {
    const RenderSettings settings = mlt::MltContext::resolve_paths(scene, given);  // mlt_paths auto
    // 1. pilot (in the context), direct pass, budget, film. Path sampler: multiplexed
    //    BDPT (default; t = 1 paths take the caustic perturbation) or the path tracer
    //    (every path takes the lens perturbation)
    mlt::MltFrame frame(scene, settings);
    const mlt::PssmltTracer& tracer = frame.ctx.tracer;
    const coherent::CmltSettings cs(settings);
    const uint64_t seed = settings.seed;
    // a chain's block costs about 1 + m·k evaluations: no more chains than blocks fit
    mlt::ChainPopulation<Chain> chains(frame, std::max<uint64_t>(1, frame.budget.chains / cs.block_cost()));
    const auto target = [&](PathCounters& c) { return coherent::make_target(tracer, scene, cs, &c, nullptr); };

    // 2. bootstrap: the points of PSSMLT's bootstrap, keys (bootstrap, i, 1)
    chains.bootstrap([&](uint64_t i, PathCounters& c, bool& invalid) {
        State s;
        s.key = StateKey{RngDomain::bootstrap, uint32_t(i), 1};
        const double v = target(c)(s);
        invalid = s.sample.invalid;
        return v;
    });

    // 3. chain starts: the given states (temporal carry-over), evaluated in this frame's
    //    scene, or the resampled pool (same numbers as pssmlt)
    chains.start(
        [&](const mlt::ChainState& in, uint32_t k, PathCounters& c, bool& invalid) {
            State x = coherent::import_state(in, StateKey{RngDomain::chain, k, 0});
            const double fx = target(c)(x);
            invalid = x.sample.invalid;
            return std::make_unique<Chain>(seed, k, cs.tries, std::move(x), fx);
        },
        [&](uint32_t i, uint32_t k, PathCounters& c) {
            const coherent::Target f = target(c);
            State x0;
            x0.key = StateKey{RngDomain::bootstrap, i, 1};
            const double f0 = f(x0);
            // Re-key to the chain: the coordinates the path read become overrides (as
            // floats, as an exported state holds them), the rest come from key (chain, k,
            // 0). A start carried into the next frame is then the same point bit for bit,
            // unread coordinates included, so with stored seeds a static scene replays the
            // chain exactly (temporal/carry.h).
            State x = coherent::import_state(coherent::export_state(x0, seed, k), StateKey{RngDomain::chain, k, 0});
            const double fx = f(x);
            CMLT_CHECK_MSG(fx == f0, "cmlt: re-keying bootstrap sample " << i << " changed its path");
            return std::make_unique<Chain>(seed, k, cs.tries, std::move(x), fx);
        },
        [&](const Chain& c) { return coherent::export_state(c.chain.x, seed, c.chain_id); });

    // 4. run the chains in rounds: outer large step, then m inner bundle steps
    coherent::BundleTotals bundles;
    chains.run(progress, [&] { return coherent::ChainTracer(tracer, scene, cs, frame.film, bundles); });

    // 5. normalisation, image and stats, merged in chain order
    std::array<mcmc::ChainStats, coherent::k_perturbation_count> pstats{};
    for (size_t c = 0; c < chains.size(); ++c)
        for (size_t i = 0; i < pstats.size(); ++i) pstats[i].merge(chains[c].perturbation[i]);
    mlt::PopulationResult merged =
        chains.finish([&](const Chain& c) { return coherent::export_state(c.chain.x, seed, c.chain_id); });
    const mcmc::KernelStats kstats = merged.kernel;
    RenderResult res = frame.finish(std::move(merged));

    MltStats& ms = res.stats.mlt;
    ms.large_step_probability = 0.0;
    mcmc::ChainStats inner;
    for (const mcmc::ChainStats& s : pstats) inner.merge(s);
    ms.small_steps = inner.steps;
    ms.acceptance_small = inner.acceptance_rate();
    ms.tries = settings.tries;
    ms.inner_length = settings.inner_length;
    ms.inner = settings.inner;
    ms.packets = settings.packets;
    ms.packet_width = settings.packets ? cs.max_width : 1;
    ms.packet_queries = frame.counters.packets.load();
    const coherent::BundleCounters& b = bundles.sum;
    ms.packet_rays = b.packet_rays;
    ms.packet_shadow_rays = b.packet_shadow_rays;
    ms.bundle_rays = b.bundle_rays;
    ms.bundle_busy_s = double(b.busy_ticks) / frame.rate.per_second();
    ms.bundle_trace_s = std::min(ms.bundle_busy_s, double(b.trace_ticks) / frame.rate.per_second());
    ms.kernel_stats_json = kernel_stats_json(kstats, pstats);
    return res;
}

}  // namespace cmlt
