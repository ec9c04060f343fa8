// PSSMLT integrator (integrators/pssmlt/): determinism over thread counts, the furnace
// (image mean = b for a grey scene, checked against b's standard error), no NaN/Inf,
// no stuck chain on a mostly black scene (light through a slit), budget accounting,
// settings errors. Convergence to PT on a Cornell-like box: tests/python/integrators/test_pssmlt.py.
#include "test_util.h"

#include "integrators/common/render.h"
#include "integrators/mlt/mlt_frame.h"
#include "util/error.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

using namespace cmlt;
using namespace cmlt::test;

namespace {

RenderSettings mlt_settings(int w, int h, int spp, uint64_t seed = 1) {
    RenderSettings st;
    st.width = w;
    st.height = h;
    st.spp = spp;
    st.seed = seed;
    st.threads = 2;
    st.integrator = "pssmlt";
    st.chains = 64;
    st.bootstrap_samples = 4096;
    st.mlt_paths = "all";  // the chains' machinery (a diffuse scene: auto would leave no chains)
    return st;
}

double channel_mean(const RenderResult& r, int c) {
    double s = 0;
    const size_t n = size_t(r.width) * r.height;
    for (size_t i = 0; i < n; ++i) s += r.image[3 * i + c];
    return s / double(n);
}

bool all_finite(const RenderResult& r) {
    for (float v : r.image)
        if (!std::isfinite(v)) return false;
    return true;
}

/// Camera inside a closed cube of albedo a emitting Le everywhere: L = Le / (1 - a).
void furnace_scene(Scene& s, float albedo, float le) {
    s.set_materials({Material{Spectrum(albedo), Spectrum(le)}});
    uint32_t m = s.add_mesh("/furnace", cube_mesh(1.f));
    s.add_instance(m, Mat4::rotate(20, 1, 1, 0));
    s.set_camera(camera_at(Mat4::translate(0.1, 0.2, 0.3) * Mat4::rotate(70, 0.2, 1, 0)));
    s.commit();
}

/// Quads, a sphere light, an emissive quad and a coloured dome (as test_path.cpp).
void mixed_scene(Scene& s) {
    s.set_materials({Material{Spectrum(0.6f, 0.5f, 0.4f), Spectrum(0.f)},
                     Material{Spectrum(0.f), Spectrum(5.f, 4.f, 3.f)}});
    uint32_t floor = s.add_mesh("/floor", quad_mesh(Vec3(0.f), Vec3(2, 0, 0), Vec3(0, 0, -2)));
    uint32_t wall = s.add_mesh("/wall", quad_mesh(Vec3(0, 1, -1), Vec3(1, 0, 0), Vec3(0, 1, 0)));
    uint32_t lamp = s.add_mesh("/lamp", quad_mesh(Vec3(0, 1.9f, 0), Vec3(0.3f, 0, 0), Vec3(0, 0, 0.3f), 1));
    s.add_instance(floor, Mat4());
    s.add_instance(wall, Mat4());
    s.add_instance(lamp, Mat4());
    s.add_light(sphere_light(Vec3(0.5f, 0.5f, 0.f), 0.1f, Spectrum(3.f)));
    LightDesc dome;
    dome.kind = LightDesc::Kind::dome;
    dome.radiance = Spectrum(0.1f, 0.1f, 0.2f);
    s.add_light(dome);
    s.set_camera(camera_at(Mat4::translate(0, 1, 3), 35.f, 36.f));
    s.commit();
}

/// A floor seen from above, under an opaque ceiling with a narrow slit; a small emissive
/// quad above the slit. Only a thin strip of the floor is lit: most of the image (and of
/// primary sample space) is black.
void slit_scene(Scene& s) {
    s.set_materials({Material{Spectrum(0.7f), Spectrum(0.f)}, Material{Spectrum(0.f), Spectrum(400.f)},
                     Material{Spectrum(0.f), Spectrum(0.f)}});
    // floor y = 0 (normal up); black ceiling y = 1 made of two slabs leaving a slit |x| < 0.02
    uint32_t floor = s.add_mesh("/floor", quad_mesh(Vec3(0.f), Vec3(3, 0, 0), Vec3(0, 0, -3)));
    uint32_t left = s.add_mesh("/left", quad_mesh(Vec3(-1.52f, 1, 0), Vec3(1.5f, 0, 0), Vec3(0, 0, 3), 2));
    uint32_t right = s.add_mesh("/right", quad_mesh(Vec3(1.52f, 1, 0), Vec3(1.5f, 0, 0), Vec3(0, 0, 3), 2));
    // lamp facing down
    uint32_t lamp = s.add_mesh("/lamp", quad_mesh(Vec3(0, 1.3f, 0), Vec3(0.05f, 0, 0), Vec3(0, 0, 0.05f), 1));
    for (uint32_t m : {floor, left, right, lamp}) s.add_instance(m, Mat4());
    // camera between floor and ceiling, looking down at the floor
    s.set_camera(camera_at(Mat4::translate(0, 0.8f, 0) * Mat4::rotate(-90, 1, 0, 0), 18.f, 36.f));
    s.commit();
}

}  // namespace

TEST(Pssmlt, DeterministicAcrossThreadCounts) {
    Scene s;
    mixed_scene(s);
    RenderSettings st = mlt_settings(32, 24, 8, 42);
    st.threads = 1;
    RenderResult a = render(s, st);
    st.threads = 2;
    RenderResult b = render(s, st);
    ASSERT_EQ(a.image.size(), b.image.size());
    EXPECT_EQ(std::memcmp(a.image.data(), b.image.data(), a.image.size() * sizeof(float)), 0);
    EXPECT_EQ(a.stats.rays, b.stats.rays);
    EXPECT_EQ(a.stats.mlt.b, b.stats.mlt.b);
    EXPECT_EQ(a.stats.mlt.max_rejection_streak, b.stats.mlt.max_rejection_streak);
    st.seed = 43;
    RenderResult c = render(s, st);
    EXPECT_NE(std::memcmp(a.image.data(), c.image.data(), a.image.size() * sizeof(float)), 0);
    EXPECT_GT(channel_mean(a, 1), 0.0);
    EXPECT_TRUE(all_finite(a));
}

TEST(Pssmlt, BudgetAndStats) {
    Scene s;
    mixed_scene(s);
    RenderSettings st = mlt_settings(32, 24, 16);
    st.large_step_probability = 0.25;
    st.direct_fraction = 0.1875;  // pilot 1 spp + direct 3 spp (0.1875 x 16) of the 16
    RenderResult r = render(s, st);
    const MltStats& m = r.stats.mlt;
    ASSERT_TRUE(m.enabled);
    const uint64_t pixels = 32 * 24, budget = pixels * (16 - 1 - 3);
    EXPECT_EQ(m.pilot_evaluations, pixels);
    EXPECT_EQ(m.direct_evaluations, 3 * pixels);
    EXPECT_EQ(m.min_depth, 2);
    EXPECT_EQ(m.bootstrap_samples, 4096u);
    EXPECT_EQ(m.mutations, budget - 4096u);
    EXPECT_EQ(m.path_evaluations, 16 * pixels);
    EXPECT_EQ(m.chains, 64u);
    EXPECT_EQ(m.small_steps + m.large_steps, m.mutations);
    // large steps are drawn with probability 0.25: 5 binomial sd
    const double n = double(m.mutations);
    EXPECT_NEAR(double(m.large_steps), 0.25 * n, 5 * std::sqrt(n * 0.25 * 0.75));
    EXPECT_GT(m.acceptance_small, m.acceptance_large);
    EXPECT_GT(m.acceptance_large, 0.0);
    EXPECT_GT(m.b, 0.0);
    EXPECT_GT(m.b_stderr, 0.0);
    EXPECT_LT(m.b_stderr, m.b_bootstrap_stderr);  // large steps refine b
    EXPECT_EQ(r.stats.nan_samples, 0u);
    EXPECT_EQ(m.clamped_splats, 0u);
    // the bootstrap is capped at half of the budget
    st.bootstrap_samples = 1000000;
    RenderResult r2 = render(s, st);
    EXPECT_EQ(r2.stats.mlt.bootstrap_samples, budget / 2);
    EXPECT_EQ(r2.stats.mlt.mutations, budget - budget / 2);
    EXPECT_NE(m.kernel_stats_json.find("\"small_step\""), std::string::npos);
    // the direct pass is its share of spp, the pilot at most spp/8 (a small budget stays
    // the chains'); the luminance target needs no pilot; no direct pass: chains do all
    st.bootstrap_samples = 4096;
    st.spp = 8;
    st.direct_fraction = 0.5;
    RenderResult r3 = render(s, st);
    EXPECT_EQ(r3.stats.mlt.direct_evaluations, 4 * pixels);
    EXPECT_EQ(r3.stats.mlt.pilot_evaluations, pixels);
    st.importance = "luminance";
    st.direct_fraction = 0;
    RenderResult r4 = render(s, st);
    EXPECT_EQ(r4.stats.mlt.pilot_evaluations, 0u);
    EXPECT_EQ(r4.stats.mlt.direct_evaluations, 0u);
    EXPECT_EQ(r4.stats.mlt.min_depth, 0);
    EXPECT_EQ(r4.stats.mlt.bootstrap_samples, 8 * pixels / 2);  // capped at half
    EXPECT_EQ(r4.stats.mlt.mutations, 8 * pixels - 8 * pixels / 2);
}

TEST(Pssmlt, FurnaceMeanIsBWithinItsStandardError) {
    // Grey furnace: every splat carries L/f* = (1,1,1) (ACEScg weights sum to 1), so the
    // image mean is exactly b; b must match Le/(1-a) = 2 within 4.5 standard errors
    // (two-sided false-alarm rate 7e-6). (Pixel-block agreement: tests/python/integrators/test_pssmlt.py.)
    Scene s;
    furnace_scene(s, 0.5f, 1.f);
    RenderSettings st = mlt_settings(16, 16, 64);
    // the image mean is b for the one-pixel box; a wider filter's chains cover the film
    // window beyond the image, so b is the window's (larger) integral
    st.pixel_filter = "box";
    st.bootstrap_samples = 8192;
    st.importance = "luminance";  // the image mean is b only for f* = luminance and
    st.direct_fraction = 0;       // chains that render every depth
    RenderResult r = render(s, st);
    const MltStats& m = r.stats.mlt;
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(channel_mean(r, c), m.b, 1e-4 * m.b);
    EXPECT_LT(m.b_stderr, 0.02);  // the check below is not vacuous
    EXPECT_LT(std::fabs(m.b - 2.0), 4.5 * m.b_stderr) << "b " << m.b << " +- " << m.b_stderr;
    EXPECT_LT(std::fabs(m.b_bootstrap - 2.0), 4.5 * m.b_bootstrap_stderr);
    EXPECT_TRUE(all_finite(r));
    // power: the same check rejects a 5% wrong answer
    EXPECT_GT(std::fabs(m.b - 2.1), 4.5 * m.b_stderr);
}

TEST(Pssmlt, MostlyBlackSceneHasNoStuckChainAndNoNaN) {
    Scene s;
    slit_scene(s);
    RenderSettings st = mlt_settings(32, 32, 64, 3);
    st.chains = 32;  // ~1900 mutations per chain
    st.direct_fraction = 0;  // the chains render the directly lit strip too
    RenderResult r = render(s, st);
    const MltStats& m = r.stats.mlt;
    EXPECT_TRUE(all_finite(r));
    EXPECT_EQ(r.stats.nan_samples, 0u);
    // most of primary sample space is black
    EXPECT_LT(double(m.bootstrap_nonzero), 0.2 * double(m.bootstrap_samples));
    EXPECT_GT(m.bootstrap_nonzero, 0u);
    // most of the image is black, and the lit strip is found
    int black = 0;
    for (int i = 0; i < 32 * 32; ++i) black += r.image[3 * i + 1] == 0.f ? 1 : 0;
    EXPECT_GT(black, 32 * 32 / 2);
    EXPECT_GT(channel_mean(r, 1), 0.0);
    // chains move: small steps are accepted often and no chain rejects for long
    EXPECT_GT(m.acceptance_small, 0.3);
    EXPECT_LT(m.max_rejection_streak, 200u) << "a chain stuck for " << m.max_rejection_streak << " steps";
    EXPECT_GT(m.mutations / m.chains, 1000u);
}

TEST(Pssmlt, SettingsErrorsNameTheField) {
    Scene s;
    furnace_scene(s, 0.5f, 1.f);
    auto expect_error = [&](auto mutate, const char* field) {
        RenderSettings st = mlt_settings(8, 8, 4);
        mutate(st);
        try {
            render(s, st);
            ADD_FAILURE() << field << ": no error";
        } catch (const SettingsError& e) {
            EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
        }
    };
    expect_error([](RenderSettings& st) { st.sigma = 0.0; }, "sigma");
    expect_error([](RenderSettings& st) { st.sigma = 1.5; }, "sigma");
    expect_error([](RenderSettings& st) { st.large_step_probability = -0.1; }, "large_step_probability");
    expect_error([](RenderSettings& st) { st.large_step_probability = 1.1; }, "large_step_probability");
    expect_error([](RenderSettings& st) { st.chains = 0; }, "chains");
    expect_error([](RenderSettings& st) { st.bootstrap_samples = -1; }, "bootstrap_samples");
    expect_error([](RenderSettings& st) { st.integrator = "mlt"; }, "integrator");
}

TEST(Pssmlt, ProgressAndCancel) {
    Scene s;
    furnace_scene(s, 0.5f, 1.f);
    RenderSettings st = mlt_settings(16, 16, 32);
    int calls = 0;
    RenderResult r = render(s, st, [&](uint64_t done, uint64_t total) {
        EXPECT_EQ(total, 32u);
        EXPECT_LE(done, total);
        return ++calls < 3;
    });
    EXPECT_TRUE(r.cancelled);
    EXPECT_EQ(calls, 3);
    EXPECT_GT(r.stats.mlt.mutations, 0u);
    EXPECT_LT(r.stats.mlt.mutations, uint64_t(16 * 16 * 32) - r.stats.mlt.bootstrap_samples);
    // normalised by the mutations taken: still the furnace value
    EXPECT_NEAR(channel_mean(r, 0), 2.0, 0.2);
}

TEST(Pssmlt, BlackSceneGivesABlackImage) {
    Scene s;
    furnace_scene(s, 0.5f, 0.f);  // nothing emits: no chain can start
    RenderResult r = render(s, mlt_settings(8, 8, 4));
    EXPECT_EQ(channel_mean(r, 0), 0.0);
    EXPECT_EQ(r.stats.mlt.chains, 0u);
    EXPECT_EQ(r.stats.mlt.b, 0.0);
}

// bootstrap_samples 0 (auto, mlt_frame.h bootstrap_size): the default size where most
// uniform samples carry light or the budget leaves no room, else about one sample that
// carries light per chain, from a probe of its own numbers; the same on any thread count.
TEST(Pssmlt, AutoBootstrapSizeGivesAboutOneLitSamplePerChain) {
    Scene s;
    slit_scene(s);
    RenderSettings st = mlt_settings(64, 64, 256, 5);
    st.bootstrap_samples = 0;
    st.direct_fraction = 0;
    st.chains = 1500;  // 0.8 % of the samples pass the slit: ~190,000 samples, below the cap
    const uint64_t left = uint64_t(st.spp) * 64 * 64 - 64 * 64;  // the pilot's 1 spp
    RenderResult a = render(s, st);
    const MltStats& m = a.stats.mlt;
    ASSERT_EQ(m.bootstrap_probe, mlt::k_bootstrap_probe);
    ASSERT_GT(m.bootstrap_probe_nonzero, 0u);
    // the slit lets a few per cent of the samples through: fewer than the chains ask for
    ASSERT_LT(double(m.bootstrap_probe_nonzero) / double(m.bootstrap_probe), 0.2);
    const double want =
        std::ceil(double(st.chains) * double(m.bootstrap_probe) / double(m.bootstrap_probe_nonzero));
    const uint64_t expected = std::max<uint64_t>(100000, std::min<uint64_t>(uint64_t(0.25 * double(left)), uint64_t(want)));
    EXPECT_EQ(m.bootstrap_samples, expected);
    EXPECT_GT(m.bootstrap_samples, 100000u);
    ASSERT_LT(want, 0.25 * double(left));  // not capped:
    // about one lit sample per chain (the probe's share of lit samples has a relative
    // standard error of 1/sqrt(its ~130 lit samples), 9 %: 3.3 of them either way)
    EXPECT_GT(double(m.bootstrap_nonzero), 0.7 * double(st.chains));
    EXPECT_LT(double(m.bootstrap_nonzero), 1.3 * double(st.chains));
    // the probe's evaluations are reported with the frame's
    EXPECT_GE(m.path_evaluations, m.pilot_evaluations + m.bootstrap_probe + m.bootstrap_samples + m.mutations);
    // the same size, bootstrap and image on one thread
    st.threads = 1;
    RenderResult b = render(s, st);
    EXPECT_EQ(b.stats.mlt.bootstrap_samples, m.bootstrap_samples);
    EXPECT_EQ(b.stats.mlt.bootstrap_probe_nonzero, m.bootstrap_probe_nonzero);
    ASSERT_EQ(a.image.size(), b.image.size());
    EXPECT_EQ(std::memcmp(a.image.data(), b.image.data(), a.image.size() * sizeof(float)), 0);
    // a set size is used as it is (no probe)
    st.threads = 2;
    st.bootstrap_samples = 4096;
    RenderResult c = render(s, st);
    EXPECT_EQ(c.stats.mlt.bootstrap_probe, 0u);
    EXPECT_EQ(c.stats.mlt.bootstrap_samples, 4096u);
    // where the budget leaves no room to grow (a quarter of it below the default): the
    // default's size, capped at half of the budget as before, and no probe
    st.bootstrap_samples = 0;
    st.spp = 16;
    RenderResult d = render(s, st);
    EXPECT_EQ(d.stats.mlt.bootstrap_probe, 0u);
    EXPECT_EQ(d.stats.mlt.bootstrap_samples, std::min<uint64_t>(100000, (16 - 1) * 64 * 64 / 2));
}

TEST(Pssmlt, AutoBootstrapSizeKeepsTheDefaultWhereMostSamplesCarryLight) {
    Scene s;
    furnace_scene(s, 0.5f, 1.f);
    RenderSettings st = mlt_settings(64, 64, 128, 5);
    st.bootstrap_samples = 0;
    st.direct_fraction = 0;
    RenderResult r = render(s, st);
    EXPECT_EQ(r.stats.mlt.bootstrap_probe, mlt::k_bootstrap_probe);
    EXPECT_GT(r.stats.mlt.bootstrap_probe_nonzero, r.stats.mlt.bootstrap_probe / 2);
    EXPECT_EQ(r.stats.mlt.bootstrap_samples, 100000u);
}
