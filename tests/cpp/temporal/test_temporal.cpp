// Temporal carry-over (src/core/temporal/carry.h): systematic resampling, keyed
// uniforms, the ratio statistics (a 1-D toy with a "light switched on"), evaluate_states
// on a real render's final chain states (same scene: the same f* bit for bit), the
// bootstrap points given to the render, the coupled chain starts (a discrete toy: exact
// distribution; a real render: the fresh frame's expected image, and a biased variant is
// caught), screen anchors and the film offset.
#include "test_util.h"

#include "integrators/common/render.h"
#include "integrators/mlt/chain_state.h"
#include "integrators/mlt/pssmlt_tracer.h"
#include "temporal/carry.h"
#include "util/error.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>

using namespace cmlt;
using namespace cmlt::test;

namespace {

constexpr uint32_t k_keep = uint32_t(RngDomain::carry_keep);
constexpr uint32_t k_refresh = uint32_t(RngDomain::carry_refresh);

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

/// A floor and a wall lit by a small lamp at x = lamp_x (direct and one-bounce light).
void lamp_scene(Scene& s, float lamp_x) {
    s.set_materials({Material{Spectrum(0.7f), Spectrum(0.f)}, Material{Spectrum(0.f), Spectrum(60.f)}});
    const uint32_t floor = s.add_mesh("/floor", quad_mesh(Vec3(0.f), Vec3(3, 0, 0), Vec3(0, 0, -3)));
    const uint32_t wall = s.add_mesh("/wall", quad_mesh(Vec3(0, 0.7f, -0.6f), Vec3(3, 0, 0), Vec3(0, 1.5f, 0)));
    const uint32_t lamp = s.add_mesh("/lamp", quad_mesh(Vec3(lamp_x, 0.9f, 0), Vec3(0.2f, 0, 0), Vec3(0, 0, 0.2f), 1));
    for (uint32_t m : {floor, wall, lamp}) s.add_instance(m, Mat4());
    s.set_camera(camera_at(Mat4::translate(0, 0.6f, 1.2f) * Mat4::rotate(-25, 1, 0, 0), 18.f, 36.f));
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
            if (k) { EXPECT_LE(picks[k - 1], picks[k]); }
            ++count[picks[k]];
        }
        for (size_t i = 0; i < w.size(); ++i) {
            const double expect = 70.0 * w[i] / total;
            EXPECT_GE(count[i], std::floor(expect) - 1e-9) << i;
            EXPECT_LE(count[i], std::ceil(expect) + 1e-9) << i;
            if (w[i] == 0.0) { EXPECT_EQ(count[i], 0); }
        }
    }
    EXPECT_TRUE(temporal::systematic_resample({0.0, 0.0}, 5, 0.5).empty());
    // deterministic: the same uniform, the same picks
    EXPECT_EQ(temporal::systematic_resample(w, 33, 0.42), temporal::systematic_resample(w, 33, 0.42));
}

TEST(Temporal, KeyedUniformIsKeyed) {
    using temporal::keyed_uniform;
    EXPECT_EQ(keyed_uniform(7, k_keep, 3, 5), keyed_uniform(7, k_keep, 3, 5));
    EXPECT_NE(keyed_uniform(7, k_keep, 3, 5), keyed_uniform(7, k_keep, 3, 6));
    EXPECT_NE(keyed_uniform(7, k_keep, 3, 5), keyed_uniform(7, k_keep, 4, 5));
    EXPECT_NE(keyed_uniform(7, k_keep, 3, 5), keyed_uniform(7, k_refresh, 3, 5));
    double mean = 0;
    for (uint32_t k = 0; k < 10000; ++k) {
        const double u = keyed_uniform(9, k_keep, k, 1);
        ASSERT_GE(u, 0.0);
        ASSERT_LT(u, 1.0);
        mean += u / 10000;
    }
    EXPECT_NEAR(mean, 0.5, 0.01);
}

// Ratio statistics on a 1-D toy: old target f0 = 1 + 30·1[0.2,0.3) on [0, 0.5), 0 on
// [0.5, 1); new target f1 = f0 + 60·1[0.7,0.75) (a light switched on where the old target
// is black). Over states ∝ f0, mean(f1/f0) is blind to the new light (why the carry-over
// couples on the bootstrap points, whose Σ f1 / Σ f0 sees it).
TEST(Temporal, RatioStatisticsAreBlindToNewLight) {
    auto f0 = [](double x) { return x < 0.5 ? 1.0 + (x >= 0.2 && x < 0.3 ? 30.0 : 0.0) : 0.0; };
    auto f1 = [&](double x) { return f0(x) + (x >= 0.7 && x < 0.75 ? 60.0 : 0.0); };
    const double b0 = 3.5;
    const size_t nc = 4000;
    std::vector<double> fo, fn;
    for (size_t i = 0; i < nc; ++i) {
        const double u = (double(i) + 0.5) / double(nc) * b0;  // cumulative mass
        double x;
        if (u < 0.2) x = u;
        else if (u < 0.2 + 3.1) x = 0.2 + (u - 0.2) / 31.0;
        else x = 0.3 + (u - 3.3);
        fo.push_back(f0(x));
        fn.push_back(f1(x));
    }
    // b0 · mean(f1/f0) = b0, while b1 = 6.5
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
        // bootstrap points are keyed: the same twice
        auto p1 = temporal::bootstrap_states(s, st, 64), p2 = temporal::bootstrap_states(s, st, 64);
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

// couple_starts on a discrete toy: M bootstrap points with old and new probabilities p, q
// (a region that dims, one that brightens, one that switches on where p = 0, and a part
// that does not change). Frame f's starts are drawn ∝ p; the coupled starts must be
// distributed ∝ q (chi-square over many trials), keep their old start with probability
// 1 − TV, and never move where q = p.
TEST(Temporal, CoupledStartsAreDistributedAsFreshOnesAndKeepWhatDidNotChange) {
    const size_t M = 40;
    std::vector<double> f_old(M), f_new(M);
    for (size_t i = 0; i < M; ++i) {
        const double base = 1.0 + double(i % 7);
        f_old[i] = i < 30 ? base : 0.0;                      // 30..39: black in frame f
        f_new[i] = i < 10 ? base : i < 20 ? 0.3 * base : i < 30 ? 2.0 * base : 4.0;
    }
    double so = 0, sn = 0;
    for (size_t i = 0; i < M; ++i) so += f_old[i], sn += f_new[i];
    double tv = 0;
    for (size_t i = 0; i < M; ++i) tv += std::max(0.0, f_new[i] / sn - f_old[i] / so);
    const uint64_t n = 64;
    const int trials = 4000;
    std::vector<double> count(M, 0.0);
    double kept = 0;
    for (int t = 0; t < trials; ++t) {
        const double u0 = temporal::keyed_uniform(99, uint32_t(RngDomain::test), 0, uint32_t(t));
        const std::vector<uint64_t> prev = temporal::systematic_resample(f_old, n, u0);
        ASSERT_EQ(prev.size(), n);
        const temporal::CoupledStarts c = temporal::couple_starts(f_old, f_new, prev, n, 7, uint32_t(t));
        ASSERT_EQ(c.picks.size(), n);
        EXPECT_EQ(c.kept + c.refreshed + c.fresh, n);
        EXPECT_EQ(c.fresh, 0u);
        EXPECT_NEAR(c.tv, tv, 1e-12);
        kept += double(c.kept);
        for (uint64_t k = 0; k < n; ++k) {
            ASSERT_LT(c.picks[k], M);
            count[c.picks[k]] += 1;
            // an unchanged or brighter start is always kept
            const size_t i = prev[k];
            if (f_new[i] / sn >= f_old[i] / so) { EXPECT_EQ(c.picks[k], i); }
        }
    }
    // expected counts ∝ q: chi-square with M − 1 degrees of freedom (p = 1e-4 bound ~ 83 for 39)
    const double total = double(trials) * double(n);
    double chi2 = 0;
    for (size_t i = 0; i < M; ++i) {
        const double e = total * f_new[i] / sn;
        chi2 += (count[i] - e) * (count[i] - e) / e;
    }
    EXPECT_LT(chi2, 83.0);
    EXPECT_NEAR(kept / total, 1.0 - tv, 0.01);

    // static: every chain keeps its start
    const std::vector<uint64_t> prev = temporal::systematic_resample(f_old, n, 0.3);
    const temporal::CoupledStarts same = temporal::couple_starts(f_old, f_old, prev, n, 7, 1);
    EXPECT_EQ(same.picks, prev);
    EXPECT_EQ(same.kept, n);
    EXPECT_EQ(same.tv, 0.0);
    // first frame (no previous starts): a fresh systematic resampling ∝ f_new
    const temporal::CoupledStarts first = temporal::couple_starts({}, f_new, {}, n, 7, 1);
    EXPECT_EQ(first.fresh, n);
    EXPECT_EQ(first.kept, 0u);
    // more chains than before: the new ones start fresh; all black: no starts
    const temporal::CoupledStarts more = temporal::couple_starts(f_old, f_old, prev, n + 5, 7, 1);
    EXPECT_EQ(more.fresh, 5u);
    EXPECT_TRUE(temporal::couple_starts(f_old, std::vector<double>(M, 0.0), prev, n, 7, 1).picks.empty());
}

TEST(Temporal, BootstrapStatesAreTheRendersBootstrap) {
    Scene s;
    slit_scene(s);
    RenderSettings st;
    st.width = 24;
    st.height = 16;
    st.spp = 32;
    st.seed = 3;
    st.threads = 2;
    st.integrator = "pssmlt";
    st.chains = 16;
    st.bootstrap_samples = 2048;
    st.direct_fraction = 0;
    const uint64_t n = temporal::bootstrap_count(st);
    ASSERT_EQ(n, 2048u);
    const auto boot = temporal::bootstrap_states(s, st, n);
    RenderResult a = render(s, st);
    ASSERT_EQ(a.bootstrap_f.size(), n);
    int nonzero = 0;
    for (size_t i = 0; i < n; ++i) {
        EXPECT_NEAR(boot->chains[i].f_star, a.bootstrap_f[i], 1e-5 * (1.0 + a.bootstrap_f[i])) << i;
        nonzero += boot->chains[i].f_star > 0;
    }
    EXPECT_GT(nonzero, 0);
    // given to the render, it is not evaluated again and b is the same
    std::vector<double> f;
    for (const auto& c : boot->chains) f.push_back(c.f_star);
    st.mlt_bootstrap_f = std::make_shared<const std::vector<double>>(f);
    RenderResult b = render(s, st);
    ASSERT_EQ(b.bootstrap_f.size(), f.size());
    for (size_t i = 0; i < n; ++i) EXPECT_EQ(b.bootstrap_f[i], float(f[i]));
    EXPECT_NEAR(b.stats.mlt.b_bootstrap, a.stats.mlt.b_bootstrap, 1e-5 * a.stats.mlt.b_bootstrap);
    st.mlt_bootstrap_f = std::make_shared<const std::vector<double>>(std::vector<double>(3, 1.0));
    EXPECT_THROW(render(s, st), SettingsError);
}

// The whole carry-over on a real render: chain starts coupled from frame A (the lamp
// over the slit) to frame B (the lamp moved sideways: the light falls elsewhere) give
// frame B the expected image of a fresh frame B. Over many seeds, the block means of
// (coupled B − fresh B) — paired: both share the seed's bootstrap points — are within
// their noise; a biased variant (every chain keeps its frame-A start, no reweighting)
// is caught by the same test, so it has the power to see a wrong start distribution.
TEST(Temporal, CoupledStartsGiveTheFreshFramesExpectedImage) {
    Scene a, b;
    lamp_scene(a, -0.4f);
    lamp_scene(b, 0.4f);
    const int W = 24, H = 16, seeds = 48, nb = 24;  // 4x4-pixel blocks
    const auto blocks = [&](const RenderResult& r) {
        std::vector<double> m(nb, 0.0);
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x)
                for (int c = 0; c < 3; ++c) m[size_t((y / 4) * (W / 4) + x / 4)] += r.image[size_t(3 * (y * W + x) + c)];
        return m;
    };
    std::vector<std::vector<double>> d_coupled, d_biased;
    for (int seed = 1; seed <= seeds; ++seed) {
        RenderSettings st;
        st.width = W;
        st.height = H;
        st.spp = 16;
        st.seed = uint64_t(seed);
        st.threads = 2;
        st.integrator = "pssmlt";
        st.chains = 192;
        st.bootstrap_samples = 1024;
        st.direct_fraction = 0;  // the chains render every path
        st.importance = "luminance";
        const uint64_t n = temporal::bootstrap_count(st);
        const auto boot_a = temporal::bootstrap_states(a, st, n), boot_b = temporal::bootstrap_states(b, st, n);
        std::vector<double> fa, fb;
        for (const auto& c : boot_a->chains) fa.push_back(c.f_star);
        for (const auto& c : boot_b->chains) fb.push_back(c.f_star);
        const temporal::CoupledStarts sa = temporal::couple_starts({}, fa, {}, 192, st.seed, 1);
        const temporal::CoupledStarts sb = temporal::couple_starts(fa, fb, sa.picks, 192, st.seed, 2);
        ASSERT_GT(sb.tv, 0.2);  // the light really moved
        const RenderResult fresh = render(b, st);
        st.mlt_bootstrap_f = std::make_shared<const std::vector<double>>(fb);
        st.mlt_initial_states = temporal::gather_states(*boot_b, *boot_b, sb.picks, 0);
        const RenderResult coupled = render(b, st);
        st.mlt_initial_states = temporal::gather_states(*boot_b, *boot_b, sa.picks, 0);
        const RenderResult biased = render(b, st);
        const auto f = blocks(fresh), c = blocks(coupled), x = blocks(biased);
        std::vector<double> dc(nb), dx(nb);
        for (int i = 0; i < nb; ++i) {
            dc[size_t(i)] = c[size_t(i)] - f[size_t(i)];
            dx[size_t(i)] = x[size_t(i)] - f[size_t(i)];
        }
        d_coupled.push_back(dc);
        d_biased.push_back(dx);
    }
    // sum of squared z-scores of the blocks' mean paired differences (blocks where the
    // renders never differ are left out)
    const auto chi2 = [&](const std::vector<std::vector<double>>& d, int* dof) {
        double sum = 0;
        *dof = 0;
        for (int i = 0; i < nb; ++i) {
            double m = 0, m2 = 0;
            for (const auto& v : d) m += v[size_t(i)];
            m /= double(d.size());
            for (const auto& v : d) m2 += (v[size_t(i)] - m) * (v[size_t(i)] - m);
            const double se = std::sqrt(m2 / double(d.size() - 1) / double(d.size()));
            if (!(se > 0)) continue;
            sum += (m / se) * (m / se);
            ++*dof;
        }
        return sum;
    };
    int dof_c = 0, dof_x = 0;
    const double chi_c = chi2(d_coupled, &dof_c), chi_x = chi2(d_biased, &dof_x);
    ASSERT_GT(dof_c, 8);
    // chi-square bound at p = 0.001: dof + 3.1·sqrt(2·dof) + 5 covers 8..24 dof
    const double bound = double(dof_c) + 3.1 * std::sqrt(2.0 * double(dof_c)) + 5.0;
    std::printf("coupled: chi2 %.1f (%d blocks), biased: chi2 %.1f (%d blocks), bound %.1f\n", chi_c, dof_c,
                chi_x, dof_x, bound);
    EXPECT_LT(chi_c, bound) << "dof " << dof_c;
    EXPECT_GT(chi_x, double(dof_x) + 3.1 * std::sqrt(2.0 * double(dof_x)) + 5.0) << "dof " << dof_x;
}

// Screen anchors: projected in their own frame they land where their rays went; after a
// camera move, a camera ray through the projected position hits the anchor's point.
TEST(Temporal, ScreenAnchorsFollowTheCamera) {
    Scene s;
    lamp_scene(s, 0.f);
    RenderSettings st;
    st.width = 32;
    st.height = 24;
    st.threads = 2;
    const auto anchors = temporal::screen_anchors(s, st, 8, 6);
    ASSERT_EQ(anchors.size(), 48u);
    int hits = 0;
    const auto same = temporal::project_anchors(s, st, anchors);
    for (size_t i = 0; i < anchors.size(); ++i) {
        if (anchors[i].instance < 0) {
            EXPECT_TRUE(std::isnan(same[i].x));
            continue;
        }
        ++hits;
        EXPECT_NEAR(same[i].x, anchors[i].p_raster.x, 1e-2f) << i;
        EXPECT_NEAR(same[i].y, anchors[i].p_raster.y, 1e-2f) << i;
    }
    EXPECT_GT(hits, 24);
    // the camera moves 10 cm sideways and turns a little
    s.set_camera(camera_at(Mat4::translate(0.1f, 0.6f, 1.2f) * Mat4::rotate(-3, 0, 1, 0) * Mat4::rotate(-25, 1, 0, 0),
                           18.f, 36.f));
    s.commit();
    const auto moved = temporal::project_anchors(s, st, anchors);
    const Camera camera(s.camera_desc(), st.width, st.height);
    int checked = 0;
    for (size_t i = 0; i < anchors.size(); ++i) {
        if (anchors[i].instance < 0 || !std::isfinite(moved[i].x)) continue;
        if (moved[i].x < 0 || moved[i].y < 0 || moved[i].x >= st.width || moved[i].y >= st.height) continue;
        EXPECT_GT(std::abs(moved[i].x - anchors[i].p_raster.x), 0.5f) << i;  // it did move
        const SceneHit h = s.intersect(camera.generate_ray(moved[i]));
        ASSERT_EQ(h.kind, SceneHit::Kind::surface);
        const Vec3 p = s.instance(uint32_t(anchors[i].instance)).xf.m.transform_point(anchors[i].p_object);
        EXPECT_LT(length(h.si.p - p), 1e-3f) << i;
        ++checked;
    }
    EXPECT_GT(checked, 12);
}

// The chains' film map with a key map: a film sample in key k's pixel cell lands in the
// pixel whose key is k at the same place within the pixel, the filter's ring stays put,
// and the cells' measure is kept (a stratified grid of samples gives every pixel the
// count its key's cell had); without a key map it is the film offset's torus shift.
TEST(Temporal, FilmMapPermutesPixelCells) {
    const int W = 6, H = 4;
    std::vector<uint32_t> keys(size_t(W * H)), inv(keys.size());
    for (size_t i = 0; i < keys.size(); ++i) keys[i] = uint32_t((i * 7 + 3) % keys.size());  // 7 coprime to 24
    for (size_t p = 0; p < keys.size(); ++p) inv[keys[p]] = uint32_t(p);
    for (float margin : {0.f, 1.5f}) {
        mlt::FilmMap map;
        map.pixel_of_key = inv.data();
        map.width = W;
        map.height = H;
        map.margin = margin;
        const float sx = float(W) + 2.f * margin, sy = float(H) + 2.f * margin;
        const int n = 240;  // samples per axis over the window
        std::vector<int> count(keys.size(), 0), count_mapped(keys.size(), 0);
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const Vec2 u((float(i) + 0.5f) / float(n), (float(j) + 0.5f) / float(n));
                const Vec2 v = map(u);
                ASSERT_TRUE(v.x >= 0.f && v.x < 1.f && v.y >= 0.f && v.y < 1.f);
                const float px = u.x * sx - margin, py = u.y * sy - margin;
                const float qx = v.x * sx - margin, qy = v.y * sy - margin;
                const bool inside = px >= 0.f && py >= 0.f && px < float(W) && py < float(H);
                if (!inside) {
                    EXPECT_EQ(v.x, u.x);
                    EXPECT_EQ(v.y, u.y);
                    continue;
                }
                const size_t k = size_t(int(py)) * W + size_t(int(px));
                const uint32_t p = inv[k];
                EXPECT_EQ(int(qx), int(p % W)) << i << "," << j;
                EXPECT_EQ(int(qy), int(p / W)) << i << "," << j;
                EXPECT_NEAR(qx - std::floor(qx), px - std::floor(px), 1e-4f);
                EXPECT_NEAR(qy - std::floor(qy), py - std::floor(py), 1e-4f);
                ++count[k];
                ++count_mapped[size_t(int(qy)) * W + size_t(int(qx))];
            }
        for (size_t p = 0; p < keys.size(); ++p) EXPECT_EQ(count_mapped[p], count[keys[p]]) << p;
    }
    mlt::FilmMap shift;
    shift.offset = Vec2(0.25f, 0.5f);
    const Vec2 u(0.9f, 0.1f);
    EXPECT_EQ(shift(u).x, mlt::shift_film(u, shift.offset).x);
    EXPECT_EQ(shift(u).y, mlt::shift_film(u, shift.offset).y);
}

// The film offset reparametrises the chains' film position (a bijection of the film
// square that keeps its measure): the expected image does not change. Block means over
// seeds with and without an offset, and with a key map (a permutation of the pixel
// cells), agree within their standard errors, for pssmlt and cmlt with the chains on
// every path; and the offset does move where a given state lands.
TEST(Temporal, FilmOffsetKeepsTheExpectedImage) {
    Scene s;
    lamp_scene(s, 0.2f);
    const int W = 16, H = 12, nb = 12, seeds = 24;  // 4x4-pixel blocks
    auto keys = std::make_shared<std::vector<uint32_t>>(size_t(W * H));
    for (size_t i = 0; i < keys->size(); ++i) (*keys)[i] = uint32_t((i * 37 + 11) % keys->size());  // 37 coprime to 192
    for (const char* integ : {"pssmlt", "cmlt"}) {
        std::vector<std::vector<double>> a, b, c;
        for (int seed = 1; seed <= seeds; ++seed) {
            RenderSettings st;
            st.width = W;
            st.height = H;
            st.spp = 24;
            st.seed = uint64_t(seed);
            st.threads = 2;
            st.integrator = integ;
            st.chains = 64;
            st.bootstrap_samples = 512;
            st.mlt_paths = "all";  // the chains on every path: they are what moves
            for (int k = 0; k < 3; ++k) {
                st.film_offset_x = k == 1 ? 0.37 : 0.0;
                st.film_offset_y = k == 1 ? 0.81 : 0.0;
                st.pixel_keys = k == 2 ? keys : nullptr;
                const RenderResult r = render(s, st);
                std::vector<double> m(nb, 0.0);
                for (int y = 0; y < H; ++y)
                    for (int x = 0; x < W; ++x)
                        for (int ch = 0; ch < 3; ++ch)
                            m[size_t((y / 4) * (W / 4) + x / 4)] += r.image[size_t(3 * (y * W + x) + ch)];
                (k == 0 ? a : k == 1 ? b : c).push_back(m);
            }
        }
        for (const auto* other : {&b, &c}) {
            double chi2 = 0;
            for (int i = 0; i < nb; ++i) {
                double ma = 0, mb = 0, va = 0, vb = 0;
                for (int j = 0; j < seeds; ++j) ma += a[size_t(j)][size_t(i)], mb += (*other)[size_t(j)][size_t(i)];
                ma /= seeds, mb /= seeds;
                for (int j = 0; j < seeds; ++j) {
                    va += (a[size_t(j)][size_t(i)] - ma) * (a[size_t(j)][size_t(i)] - ma);
                    vb += ((*other)[size_t(j)][size_t(i)] - mb) * ((*other)[size_t(j)][size_t(i)] - mb);
                }
                const double se2 = (va + vb) / double(seeds - 1) / double(seeds);
                ASSERT_GT(se2, 0.0);
                chi2 += (ma - mb) * (ma - mb) / se2;
            }
            EXPECT_LT(chi2, 32.9) << integ << (other == &c ? " key map" : " offset");  // chi-square, 12 dof, p = 0.001
        }
    }
    // the same state lands elsewhere
    RenderSettings st;
    st.width = W;
    st.height = H;
    st.threads = 2;
    st.integrator = "pssmlt";
    st.bootstrap_samples = 256;
    st.direct_fraction = 0;
    const auto p0 = temporal::bootstrap_states(s, st, 256);
    st.film_offset_x = 0.5;
    const auto p1 = temporal::bootstrap_states(s, st, 256);
    int differ = 0, lit = 0;
    for (size_t i = 0; i < 256; ++i) {
        lit += p0->chains[i].f_star > 0 || p1->chains[i].f_star > 0;
        differ += p0->chains[i].f_star != p1->chains[i].f_star;
    }
    EXPECT_GT(lit, 10);
    EXPECT_GT(differ, lit / 2);
    st.film_offset_x = 1.0;
    EXPECT_THROW(st.validate(), SettingsError);
}
