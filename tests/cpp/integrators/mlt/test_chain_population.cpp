// The chain population of the Metropolis frames (integrators/mlt/chain_population.h),
// driven with a toy chain whose "path" is its bootstrap index: bootstrap evaluation,
// chain starts resampled ∝ f* (and the replay check), starts from given states with
// their ids, budgets split evenly, rounds that spend every budget and report progress,
// and the merge of b in chain order.
#include "chi2.h"
#include "test_util.h"

#include "integrators/mlt/chain_population.h"
#include "integrators/mlt/mlt_frame.h"
#include "util/error.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <atomic>
#include <map>
#include <memory>
#include <string>
#include <vector>

using namespace cmlt;
using namespace cmlt::test;

namespace {

/// f* of bootstrap sample i: zero for every fourth, else 1..7.
double toy_f(uint64_t i) { return i % 4 == 0 ? 0.0 : double(1 + i % 7); }

struct ToyChain : mlt::ChainTally {
    mcmc::Chain<double> chain;
    uint32_t started_from = 0;
};

std::unique_ptr<ToyChain> toy_chain(uint32_t from, double fx) {
    auto c = std::make_unique<ToyChain>();
    c->chain.x = double(from);
    c->chain.fx = fx;
    c->started_from = from;
    return c;
}

mlt::ChainState toy_export(const ToyChain& c) {
    mlt::ChainState s;
    s.chain_id = c.chain_id;
    s.f_star = c.chain.fx;
    return s;
}

/// Steps a toy chain one evaluation at a time; every third step is a "large step" whose
/// f* value enters b.
struct ToyTracer {
    void run(ToyChain& c, uint64_t end) {
        while (c.evaluations < end) {
            mcmc::StepResult r;
            r.evaluations = 1;
            r.kind = c.steps % 3 == 0 ? mcmc::MutationKind::large_step : mcmc::MutationKind::small_step;
            if (r.kind == mcmc::MutationKind::large_step) c.large.add(double(c.chain_id % 5) + 0.25 * double(c.steps % 11));
            c.record(r);
        }
    }
    void flush(FrameCounters&) {}
};

struct Fixture {
    Scene scene;
    RenderSettings settings;
    Fixture() {
        scene.set_materials({Material{Spectrum(0.5f), Spectrum(0.f)}});
        scene.add_instance(scene.add_mesh("/floor", quad_mesh(Vec3(0.f), Vec3(1, 0, 0), Vec3(0, 0, -1))), Mat4());
        scene.set_camera(camera_at(Mat4::translate(0, 1, 3)));
        scene.commit();
        settings.width = 8;
        settings.height = 8;
        settings.spp = 64;  // 4096 evaluations: no pilot, no direct pass
        settings.threads = 2;
        settings.integrator = "pssmlt";
        settings.importance = "luminance";
        settings.direct_fraction = 0.0;
        settings.bootstrap_samples = 512;
        settings.chains = 10;
    }
};

void toy_bootstrap(mlt::ChainPopulation<ToyChain>& pop) {
    pop.bootstrap([](uint64_t i, PathCounters&, bool&) { return toy_f(i); });
}

}  // namespace

TEST(ChainPopulation, BootstrapEvaluatesEverySampleOnceAndStartsSplitTheBudget) {
    Fixture fx;
    mlt::MltFrame frame(fx.scene, fx.settings);
    ASSERT_EQ(frame.budget.bootstrap, 512u);
    ASSERT_EQ(frame.budget.chains, 4096u - 512u);
    mlt::ChainPopulation<ToyChain> pop(frame, frame.budget.chains);
    std::vector<std::atomic<int>> calls(512);
    pop.bootstrap([&](uint64_t i, PathCounters&, bool&) {
        calls[i].fetch_add(1);
        return toy_f(i);
    });
    for (size_t i = 0; i < calls.size(); ++i) ASSERT_EQ(calls[i].load(), 1) << i;
    pop.start([](const mlt::ChainState&, uint32_t, PathCounters&, bool&) -> std::unique_ptr<ToyChain> {
                  ADD_FAILURE() << "no states were given";
                  return nullptr;
              },
              [](uint32_t i, uint32_t, PathCounters&) { return toy_chain(i, toy_f(i)); }, toy_export);
    ASSERT_EQ(pop.size(), 10u);
    uint64_t total = 0, lo = ~0ull, hi = 0;
    for (size_t k = 0; k < pop.size(); ++k) {
        EXPECT_EQ(pop[k].chain_id, k);
        EXPECT_GT(toy_f(pop[k].started_from), 0.0) << "chain " << k << " started where f* = 0";
        total += pop[k].budget;
        lo = std::min(lo, pop[k].budget);
        hi = std::max(hi, pop[k].budget);
    }
    EXPECT_EQ(total, frame.budget.chains);
    EXPECT_LE(hi - lo, 1u);
    // the start states are recorded in chain order
    mlt::PopulationResult r = pop.finish(toy_export);
    ASSERT_EQ(r.start_states->chains.size(), 10u);
    for (size_t k = 0; k < 10; ++k) EXPECT_EQ(r.start_states->chains[k].chain_id, k);
    EXPECT_EQ(r.bootstrap_f.size(), 512u);
    EXPECT_FALSE(r.imported);
}

TEST(ChainPopulation, StartsAreResampledInProportionToTheTarget) {
    Fixture fx;
    fx.settings.chains = 3000;
    mlt::MltFrame frame(fx.scene, fx.settings);
    mlt::ChainPopulation<ToyChain> pop(frame, frame.budget.chains);
    toy_bootstrap(pop);
    pop.start([](const mlt::ChainState&, uint32_t, PathCounters&, bool&) { return std::unique_ptr<ToyChain>(); },
              [](uint32_t i, uint32_t, PathCounters&) { return toy_chain(i, toy_f(i)); }, toy_export);
    ASSERT_EQ(pop.size(), 3000u);
    // starts per value class f = 1..7 against Σ_{i: f(i) = v} f(i) / Σ f
    std::vector<double> observed(7, 0.0), expected(7, 0.0);
    double total_f = 0.0;
    for (uint64_t i = 0; i < 512; ++i) total_f += toy_f(i);
    for (uint64_t i = 0; i < 512; ++i)
        if (toy_f(i) > 0) expected[size_t(toy_f(i)) - 1] += 3000.0 * toy_f(i) / total_f;
    for (size_t k = 0; k < pop.size(); ++k) observed[size_t(toy_f(pop[k].started_from)) - 1] += 1.0;
    const Chi2Result c = chi2_test(observed, expected);
    EXPECT_TRUE(c.passed(1e-3)) << c.message;
}

TEST(ChainPopulation, AReplayThatChangesTheTargetIsAnError) {
    Fixture fx;
    mlt::MltFrame frame(fx.scene, fx.settings);
    mlt::ChainPopulation<ToyChain> pop(frame, frame.budget.chains);
    toy_bootstrap(pop);
    try {
        pop.start([](const mlt::ChainState&, uint32_t, PathCounters&, bool&) { return std::unique_ptr<ToyChain>(); },
                  [](uint32_t i, uint32_t, PathCounters&) { return toy_chain(i, toy_f(i) + 1.0); }, toy_export);
        FAIL() << "a replay with a different f* was accepted";
    } catch (const std::logic_error& e) {
        EXPECT_NE(std::string(e.what()).find("replaying bootstrap sample"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("pssmlt"), std::string::npos) << e.what();
    }
}

TEST(ChainPopulation, GivenStatesStartOneChainEachAndKeepTheirIds) {
    Fixture fx;
    auto given = std::make_shared<mlt::ChainStates>();
    given->path_sampler = fx.settings.mlt_path_sampler;
    for (uint64_t i = 0; i < 5; ++i) {
        mlt::ChainState s;
        s.chain_id = 100 + i;
        s.f_star = double(i + 1);
        given->chains.push_back(s);
    }
    fx.settings.mlt_initial_states = given;
    mlt::MltFrame frame(fx.scene, fx.settings);
    mlt::ChainPopulation<ToyChain> pop(frame, frame.budget.chains);
    toy_bootstrap(pop);
    pop.start(
        [](const mlt::ChainState& in, uint32_t k, PathCounters&, bool& invalid) {
            EXPECT_EQ(in.chain_id, 100u + k);
            invalid = k == 3;
            return toy_chain(k, in.f_star);
        },
        [](uint32_t, uint32_t, PathCounters&) -> std::unique_ptr<ToyChain> {
            ADD_FAILURE() << "given states must not be resampled";
            return nullptr;
        },
        toy_export);
    ASSERT_EQ(pop.size(), 5u);
    for (size_t k = 0; k < 5; ++k) EXPECT_EQ(pop[k].chain_id, 100u + k);
    EXPECT_EQ(frame.counters.invalid.load(), 1u);  // the invalid import is counted
    const mlt::PopulationResult r = pop.finish(toy_export);
    EXPECT_TRUE(r.imported);
    ASSERT_EQ(r.states->chains.size(), 5u);
    EXPECT_EQ(r.states->chains[4].chain_id, 104u);

    // states of the other path sampler cannot start these chains
    auto other = std::make_shared<mlt::ChainStates>(*given);
    other->path_sampler = "pt";
    fx.settings.mlt_initial_states = other;
    mlt::MltFrame frame2(fx.scene, fx.settings);
    try {
        mlt::ChainPopulation<ToyChain> bad(frame2, frame2.budget.chains);
        FAIL() << "states of the pt sampler started bdpt chains";
    } catch (const SettingsError& e) {
        EXPECT_NE(std::string(e.what()).find("mlt_initial_states"), std::string::npos) << e.what();
    }
}

TEST(ChainPopulation, RoundsSpendEveryBudgetReportProgressAndMergeInChainOrder) {
    Fixture fx;
    mlt::MltFrame frame(fx.scene, fx.settings);
    mlt::ChainPopulation<ToyChain> pop(frame, frame.budget.chains);
    toy_bootstrap(pop);
    pop.start([](const mlt::ChainState&, uint32_t, PathCounters&, bool&) { return std::unique_ptr<ToyChain>(); },
              [](uint32_t i, uint32_t, PathCounters&) { return toy_chain(i, toy_f(i)); }, toy_export);
    std::vector<std::pair<uint64_t, uint64_t>> calls;
    pop.run(
        [&](uint64_t done, uint64_t total) {
            calls.emplace_back(done, total);
            return true;
        },
        [] { return ToyTracer(); });
    ASSERT_FALSE(calls.empty());
    for (size_t i = 0; i < calls.size(); ++i) {
        EXPECT_EQ(calls[i].second, uint64_t(fx.settings.spp));
        if (i > 0) { EXPECT_GE(calls[i].first, calls[i - 1].first); }
    }
    EXPECT_LE(calls.size(), size_t(ChainSchedule::k_rounds));
    // b: the bootstrap, then every chain's large steps in chain order
    mcmc::NormalisationAccumulator b;
    for (uint64_t i = 0; i < 512; ++i) b.add(toy_f(i));
    uint64_t evaluations = 0;
    for (size_t k = 0; k < pop.size(); ++k) {
        EXPECT_EQ(pop[k].evaluations, pop[k].budget) << k;
        b.merge(pop[k].large);
        evaluations += pop[k].evaluations;
    }
    const mlt::PopulationResult r = pop.finish(toy_export);
    EXPECT_FALSE(r.cancelled);
    EXPECT_EQ(r.evaluations, frame.budget.chains);
    EXPECT_EQ(r.evaluations, evaluations);
    EXPECT_EQ(r.steps, evaluations);
    EXPECT_EQ(r.b.mean, b.estimate().mean);
    EXPECT_EQ(r.b.std_error, b.estimate().std_error);
    EXPECT_EQ(r.kernel[mcmc::MutationKind::large_step].steps + r.kernel[mcmc::MutationKind::small_step].steps,
              r.steps);
}

TEST(ChainPopulation, ProgressCanStopTheRounds) {
    Fixture fx;
    mlt::MltFrame frame(fx.scene, fx.settings);
    mlt::ChainPopulation<ToyChain> pop(frame, frame.budget.chains);
    toy_bootstrap(pop);
    pop.start([](const mlt::ChainState&, uint32_t, PathCounters&, bool&) { return std::unique_ptr<ToyChain>(); },
              [](uint32_t i, uint32_t, PathCounters&) { return toy_chain(i, toy_f(i)); }, toy_export);
    int calls = 0;
    pop.run(
        [&](uint64_t, uint64_t) {
            ++calls;
            return false;
        },
        [] { return ToyTracer(); });
    EXPECT_EQ(calls, 1);
    const mlt::PopulationResult r = pop.finish(toy_export);
    EXPECT_TRUE(r.cancelled);
    EXPECT_LT(r.evaluations, frame.budget.chains);
    EXPECT_GT(r.evaluations, 0u);
}

// The error groups of resampled chains: every start sample's chains in one group, the
// groups' chain counts as even as whole start samples allow, groups left empty only when
// there are fewer start samples than groups.
TEST(ChainPopulation, ErrorGroupsAreDisjointStartSamples) {
    const std::vector<size_t> pick = {3, 3, 3, 3, 5, 5, 9, 11, 11, 11, 20, 21, 21, 40, 40, 40};
    const std::vector<int> g = mlt::start_sample_groups(pick, 4);
    ASSERT_EQ(g.size(), pick.size());
    std::map<size_t, int> group_of;
    std::vector<int> count(4, 0);
    for (size_t k = 0; k < pick.size(); ++k) {
        ASSERT_GE(g[k], 0);
        ASSERT_LT(g[k], 4);
        auto it = group_of.emplace(pick[k], g[k]).first;
        EXPECT_EQ(it->second, g[k]) << "start sample " << pick[k] << " split over groups";
        ++count[size_t(g[k])];
    }
    // 16 chains from starts of 4, 3, 3, 2, 2, 1, 1 chains: 4 per group
    for (int c : count) EXPECT_EQ(c, 4);
    // two start samples, three groups: one group stays empty
    const std::vector<int> few = mlt::start_sample_groups({7, 7, 8}, 3);
    EXPECT_EQ(few[0], few[1]);
    EXPECT_NE(few[0], few[2]);
}
