// Temporal carry-over (src/core/temporal/carry.h): systematic resampling, the
// deterministic-mixture importance resampling of carried + pool particles (a 1-D toy
// with a "light switched on" where the old target had almost nothing), the ratio
// statistics, and evaluate_states on a real render's final chain states (same scene:
// the same f* bit for bit; the render then starts every chain from them).
#include "test_util.h"

#include "integrators/common/render.h"
#include "integrators/mlt/chain_state.h"
#include "temporal/carry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>

using namespace cmlt;
using namespace cmlt::test;

namespace {

/// A floor under a ceiling with a slit, lit by a small emissive quad (as integrators/pssmlt/test_pssmlt.cpp).
void slit_scene(Scene& s) {
    s.set_materials({Material{Spectrum(0.7f), Spectrum(0.f)}, Material{Spectrum(0.f), Spectrum(400.f)},
                     Material{Spectrum(0.f), Spectrum(0.f)}});
    uint32_t floor = s.add_mesh("/floor", quad_mesh(Vec3(0.f), Vec3(3, 0, 0), Vec3(0, 0, -3)));
    uint32_t left = s.add_mesh("/left", quad_mesh(Vec3(-1.42f, 1, 0), Vec3(1.4f, 0, 0), Vec3(0, 0, 3), 2));
    uint32_t right = s.add_mesh("/right", quad_mesh(Vec3(1.42f, 1, 0), Vec3(1.4f, 0, 0), Vec3(0, 0, 3), 2));
    uint32_t lamp = s.add_mesh("/lamp", quad_mesh(Vec3(0, 1.3f, 0), Vec3(0.05f, 0, 0), Vec3(0, 0, 0.05f), 1));
    for (uint32_t m : {floor, left, right, lamp}) s.add_instance(m, Mat4());
    s.set_camera(camera_at(Mat4::translate(0, 0.8f, 0) * Mat4::rotate(-90, 1, 0, 0), 18.f, 36.f));
    s.commit();
}

}  // namespace

TEST(Temporal, SystematicResampleCounts) {
    const std::vector<double> w = {1.0, 0.0, 3.0, 0.5, 0.0, 2.5};
    const double total = 7.0;
    for (double u0 : {0.0, 0.3, 0.999}) {
        const auto picks = temporal::systematic_resample(w, 70, u0);
        ASSERT_EQ(picks.size(), 70u);
        std::vector<int> count(w.size(), 0);
        for (size_t k = 0; k < picks.size(); ++k) {
            ASSERT_LT(picks[k], w.size());
            if (k) EXPECT_LE(picks[k - 1], picks[k]);
            ++count[picks[k]];
        }
        for (size_t i = 0; i < w.size(); ++i) {
            const double expect = 70.0 * w[i] / total;
            EXPECT_GE(count[i], std::floor(expect) - 1e-9) << i;
            EXPECT_LE(count[i], std::ceil(expect) + 1e-9) << i;
            if (w[i] == 0.0) EXPECT_EQ(count[i], 0);
        }
    }
    EXPECT_TRUE(temporal::systematic_resample({0.0, 0.0}, 5, 0.5).empty());
    // deterministic: the same uniform, the same picks
    EXPECT_EQ(temporal::systematic_resample(w, 33, 0.42), temporal::systematic_resample(w, 33, 0.42));
}

TEST(Temporal, CarryUniformIsKeyed) {
    EXPECT_EQ(temporal::carry_uniform(7, 3), temporal::carry_uniform(7, 3));
    EXPECT_NE(temporal::carry_uniform(7, 3), temporal::carry_uniform(7, 4));
    const double u = temporal::carry_uniform(9, 1);
    EXPECT_GE(u, 0.0);
    EXPECT_LT(u, 1.0);
}

// 1-D toy: old target f0 = 1 + 30·1[0.2,0.3) on [0, 0.5), 0 on [0.5, 1); new target
// f1 = f0 + 60·1[0.7,0.75) (a light switched on where the old target is black: no carried
// particle can be there). Carried particles ~ f0 (stratified inverse CDF), pool points
// stratified uniform. The resampled starts must be distributed ∝ f1: mass 3/6.5 in the
// new light, 3.1/6.5 in the old bump.
TEST(Temporal, PlanCarryResamplesToTheNewTarget) {
    auto f0 = [](double x) { return x < 0.5 ? 1.0 + (x >= 0.2 && x < 0.3 ? 30.0 : 0.0) : 0.0; };
    auto f1 = [&](double x) { return f0(x) + (x >= 0.7 && x < 0.75 ? 60.0 : 0.0); };
    const double b0 = 3.5, b1 = 6.5;
    const size_t nc = 4000, np = 4000, n = 20000;
    std::vector<double> xc, fo, fn;
    for (size_t i = 0; i < nc; ++i) {
        const double u = (double(i) + 0.5) / double(nc) * b0;  // cumulative mass
        double x;
        if (u < 0.2) x = u;
        else if (u < 0.2 + 3.1) x = 0.2 + (u - 0.2) / 31.0;
        else x = 0.3 + (u - 3.3);
        xc.push_back(x);
        fo.push_back(f0(x));
        fn.push_back(f1(x));
    }
    std::vector<double> xp, po, pn;
    for (size_t j = 0; j < np; ++j) {
        const double x = (double(j) + 0.5) / double(np);
        xp.push_back(x);
        po.push_back(f0(x));
        pn.push_back(f1(x));
    }
    const temporal::CarryPlan plan = temporal::plan_carry(fo, fn, po, pn, b0, n, 0.37);
    ASSERT_EQ(plan.picks.size(), n);
    EXPECT_EQ(plan.from_carried + plan.from_pool, n);
    double in_new = 0, in_old = 0;
    for (uint64_t p : plan.picks) {
        const double x = p < nc ? xc[p] : xp[p - nc];
        in_new += (x >= 0.7 && x < 0.75);
        in_old += (x >= 0.2 && x < 0.3);
    }
    EXPECT_NEAR(in_new / n, 3.0 / b1, 0.01);
    EXPECT_NEAR(in_old / n, 3.1 / b1, 0.01);
    EXPECT_GT(plan.from_carried, plan.from_pool / 2);  // carried chains do most of the old part

    // carried particles alone cannot see the new light: why the pool exists
    const temporal::CarryPlan only = temporal::plan_carry(fo, fn, {}, {}, b0, n, 0.37);
    for (uint64_t p : only.picks) ASSERT_LT(xc[p], 0.5);

    // ... and the ratio estimator is blind to it too: b0 · mean(f1/f0) = b0, while the
    // fresh estimate says b1 — the disagreement is the change signal
    const temporal::RatioStats r = temporal::ratio_statistics(fo, fn);
    EXPECT_EQ(r.count, nc);
    EXPECT_DOUBLE_EQ(b0 * r.mean, b0);
    EXPECT_EQ(r.variance, 0.0);
    // a dimmer light: every ratio 0.5 → b_ratio = b0/2 exactly
    std::vector<double> half(fo);
    for (double& v : half) v *= 0.5;
    EXPECT_DOUBLE_EQ(b0 * temporal::ratio_statistics(fo, half).mean, b0 / 2);
}

TEST(Temporal, EvaluateStatesReproducesTheRendersTargetAndRestartsChains) {
    Scene s;
    slit_scene(s);
    for (const char* sampler : {"bdpt", "pt"}) {
        RenderSettings st;
        st.width = 24;
        st.height = 16;
        st.spp = 4;
        st.seed = 5;
        st.threads = 2;
        st.integrator = "pssmlt";
        st.chains = 32;
        st.bootstrap_samples = 512;
        st.mlt_path_sampler = sampler;
        st.direct_fraction = 0;  // the slit scene is all direct light: the chains render it
        RenderResult a = render(s, st);
        ASSERT_TRUE(a.mlt_states);
        const mlt::ChainStates& end = *a.mlt_states;
        ASSERT_EQ(end.chains.size(), 32u);
        auto ev = temporal::evaluate_states(s, st, end);
        ASSERT_EQ(ev->chains.size(), end.chains.size());
        for (size_t i = 0; i < end.chains.size(); ++i) {
            EXPECT_EQ(ev->chains[i].f_star, end.chains[i].f_star) << sampler << " chain " << i;
            EXPECT_EQ(ev->chains[i].chain_id, end.chains[i].chain_id);
        }
        // evaluated again: nothing left to draw, the same values
        auto ev2 = temporal::evaluate_states(s, st, *ev);
        for (size_t i = 0; i < ev->chains.size(); ++i) EXPECT_EQ(ev2->chains[i].f_star, ev->chains[i].f_star);
        // pool points are keyed: the same twice
        auto p1 = temporal::sample_pool(s, st, 9, 64), p2 = temporal::sample_pool(s, st, 9, 64);
        for (size_t j = 0; j < 64; ++j) EXPECT_EQ(p1->chains[j].f_star, p2->chains[j].f_star);
        // start the next render from a gathered population
        std::vector<uint64_t> picks;
        for (uint64_t k = 0; k < 32; ++k) picks.push_back(k % 2 ? k : 32 + k);
        auto starts = temporal::gather_states(*ev, *p1, picks, 1000);
        EXPECT_EQ(starts->chains[0].chain_id, 1000u);
        EXPECT_EQ(starts->chains[1].chain_id, ev->chains[1].chain_id);
        st.mlt_initial_states = starts;
        RenderResult b = render(s, st);
        EXPECT_EQ(b.stats.mlt.imported_chains, 32u);
        for (float v : b.image) ASSERT_TRUE(std::isfinite(v));
    }
}
