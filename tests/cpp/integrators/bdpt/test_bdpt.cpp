// Bidirectional path tracing: MIS weights sum to 1 over strategies, each unweighted
// strategy is unbiased on its own, PT and BDPT agree block by block, the closed-sphere
// furnace, no NaN with Dirac / degenerate lights, determinism over thread counts.
//
// False alarms: every statistical check below states its threshold; each test's checks
// together have a false-alarm rate of at most 1.1e-3 (Bonferroni over its comparisons;
// standard errors per channel, see image_stats.h).
#include "image_stats.h"
#include "test_scenes.h"
#include "test_util.h"

#include "integrators/bdpt/bdpt_tracer.h"
#include "integrators/common/render.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

using namespace cmlt;
using namespace cmlt::test;

namespace {

RenderSettings settings(const char* integrator, int w, int h, int spp, int depth = 64) {
    RenderSettings st;
    st.width = w;
    st.height = h;
    st.spp = spp;
    st.max_depth = depth;
    st.threads = 2;
    st.integrator = integrator;
    st.seed = 7;
    return st;
}

void cornell(Scene& s) {
    box_scene(s, 12.f, true);
    s.commit();
}

/// The Cornell box through a thin lens (r = 16 mm * 0.01 / (2 * 2) = 4 cm, focus 1.2 m).
void cornell_lens(Scene& s) {
    box_scene(s, 12.f, true);
    CameraDesc c = s.camera_desc();
    c.f_stop = 2.f;
    c.focus_distance = 1.2f;
    c.lens_unit = 0.01f;
    s.set_camera(c);
    s.commit();
}

/// The Cornell box whose block slides 0.9 m along x while the shutter is open.
void moving_block_box(Scene& s) {
    box_scene(s, 12.f, true);
    const Mat4 r = Mat4::rotate(25, 0, 1, 0);
    s.set_instance_motion(2, {Mat4::translate(-0.5, -0.7, -0.3) * r, Mat4::translate(0.4, -0.7, -0.3) * r});
    s.commit();
}

void sphere_light_box(Scene& s) {
    box_scene(s, 0.f, false);
    LightDesc sph;
    sph.kind = LightDesc::Kind::sphere;
    sph.transform = Mat4::translate(-0.4, 0.6, -0.2);
    sph.radius = 0.08f;
    sph.radiance = Spectrum(60.f, 50.f, 40.f);
    s.add_light(sph);
    s.commit();
}

void dome_scene(Scene& s) {
    s.set_materials({Material{Spectrum(0.6f, 0.5f, 0.4f), Spectrum(0.f)},
                     Material{Spectrum(0.3f, 0.5f, 0.7f), Spectrum(0.f)}});
    uint32_t floor = s.add_mesh("/floor", quad_mesh(Vec3(0.f), Vec3(3, 0, 0), Vec3(0, 0, -3)));
    s.add_instance(floor, Mat4());
    uint32_t b = s.add_mesh("/block", cube_mesh(0.5f, 1));
    s.add_instance(b, Mat4::translate(0, 0.5, 0) * Mat4::rotate(30, 0, 1, 0));
    LightDesc dome;
    dome.kind = LightDesc::Kind::dome;
    dome.radiance = Spectrum(0.8f, 0.9f, 1.f);
    s.add_light(dome);
    LightDesc sun;
    sun.kind = LightDesc::Kind::distant;
    sun.angle = 5.f;
    sun.radiance = Spectrum(300.f);
    sun.transform = Mat4::rotate(-50, 1, 0.3, 0);
    s.add_light(sun);
    s.set_camera(camera_at(Mat4::translate(0, 1.5, 3.5) * Mat4::rotate(-20, 1, 0, 0), 20.f, 36.f));
    s.commit();
}

double image_mean(const RenderResult& r) {
    double s = 0;
    for (float v : r.image) s += v;
    return s / double(r.image.size());
}

/// PT and BDPT agree (image_stats.h): per-channel 8x8 block means within their joint
/// confidence intervals (Bonferroni over blocks and channels, 1e-3 family-wise) and the
/// per-channel image means within 1% plus z(1e-4 / 3) joint standard errors (1e-4 for
/// the three; `tol` instead of 1% where given); with `require_resolution` the standard
/// errors must be small enough for a mean error of 2 tol to fail, and in every case a
/// 20% error of a bright block must fail in most blocks. False-alarm rate per call:
/// 1.1e-3.
void expect_pt_bdpt_agree(void (*make)(Scene&), int w, int h, int spp_pt, int spp_bdpt,
                          const char* what, bool require_resolution = true, double tol = 0.01,
                          const char* filter = "gaussian") {
    Scene s;
    make(s);
    RenderSettings spt = settings("pt", w, h, spp_pt), sbd = settings("bdpt", w, h, spp_bdpt);
    spt.pixel_filter = sbd.pixel_filter = filter;
    RenderResult pt = render(s, spt);
    RenderResult bd = render(s, sbd);
    EXPECT_EQ(pt.stats.nan_samples, 0u) << what;
    EXPECT_EQ(bd.stats.nan_samples, 0u) << what;
    EXPECT_GT(bd.stats.splats, 0u) << what;  // light tracing (t = 1), through a thin lens too
    AgreementOptions o;
    o.require_resolution = require_resolution;
    o.tol_mean = tol;
    expect_images_agree(pt, bd, what, o);
}

}  // namespace

// ---- MIS weights ---------------------------------------------------------------------------

TEST(Bdpt, MisWeightsSumToOne) {
    // Sample camera and light subpaths; for every connection with a contribution, the
    // production weight function evaluated on the path as every strategy would have
    // made it sums to 1, and the weight from the subpaths as sampled is the same.
    // Scenes 3-5: light tracing (t = 1) through a thin lens; cut-out and
    // ior-1 pass-through surfaces crossed by subpaths and connections (their crossing
    // probabilities enter the densities); motion blur (one shutter time per sample).
    for (int scene_kind = 0; scene_kind < 6; ++scene_kind) {
        Scene s;
        if (scene_kind == 0) cornell(s);
        else if (scene_kind == 1) sphere_light_box(s);
        else if (scene_kind == 3) cornell_lens(s);
        else if (scene_kind == 4) pass_through_box(s);
        else if (scene_kind == 5) moving_block_box(s);
        else {
            box_scene(s, 5.f, true);
            LightDesc pt;  // a point light too: Dirac position (no s = 0)
            pt.kind = LightDesc::Kind::sphere;
            pt.treat_as_point = true;
            pt.radius = 0.05f;
            pt.radiance = Spectrum(100.f);
            pt.transform = Mat4::translate(0.5, 0.5, 0.2);
            s.add_light(pt);
            s.commit();
        }
        Camera cam(s.camera_desc(), 16, 16);
        BdptTracer tr(s, cam, 16, 16, 6);
        BdptWorkspace ws;
        ws.camera.resize(8);
        ws.light.resize(7);
        BdptCounters c;
        int checked = 0, checked_t1 = 0, crossed = 0;
        for (uint32_t i = 0; i < 400; ++i) {
            PixelStreamSampler sampler(99, i, uint32_t(scene_kind));
            sampler.start_stream(0);
            Vec2 u = sampler.next2d();
            int nc = tr.generate_camera_subpath(Vec2(u.x * 16, u.y * 16), sampler, 8, false,
                                                ws.camera.data(), c);
            sampler.start_stream(1);
            int nl = tr.generate_light_subpath(sampler, 7, false, ws.light.data(), c,
                                               ws.camera[0].time);
            for (int k = 0; k < nc; ++k) crossed += ws.camera[size_t(k)].pass_pdf < 1.f;
            for (int k = 0; k < nl; ++k) crossed += ws.light[size_t(k)].pass_pdf < 1.f;
            sampler.start_stream(2);
            for (int t = 1; t <= nc; ++t)
                for (int sl = 0; sl <= nl; ++sl) {
                    if ((sl == 1 && t == 1) || sl + t < 2 || sl + t - 2 > 6) continue;
                    if (sl == 0 && ws.camera[size_t(t - 1)].infinite) continue;
                    Vec2 pr;
                    PathVertex sampled;
                    Spectrum L = tr.connect(ws.light.data(), sl, ws.camera.data(), t, sampler, &pr,
                                            false, c, &sampled);
                    if (is_black(L)) continue;
                    float here = -1.f;
                    std::vector<float> w =
                        tr.strategy_weights(ws.light.data(), sl, ws.camera.data(), t, sampled, &here);
                    double sum = 0;
                    for (float x : w) {
                        EXPECT_TRUE(std::isfinite(x));
                        EXPECT_GE(x, 0.f);
                        sum += x;
                    }
                    EXPECT_NEAR(sum, 1.0, 1e-3) << "scene " << scene_kind << " s " << sl << " t " << t;
                    EXPECT_NEAR(here, w[size_t(sl)], 1e-3 * std::max(1.f, w[size_t(sl)]))
                        << "scene " << scene_kind << " s " << sl << " t " << t;
                    ++checked;
                    checked_t1 += t == 1;
                }
        }
        EXPECT_GT(checked, 200) << "scene " << scene_kind;
        // Light tracing reaches the camera, through the lens too.
        EXPECT_GT(checked_t1, 20) << "scene " << scene_kind;
        // The walks did cross the pass-through surfaces with probability < 1.
        if (scene_kind == 4) EXPECT_GT(crossed, 20);
        std::printf("scene %d: %d connections checked, %d of them t = 1, %d vertices after crossings\n",
                    scene_kind, checked, checked_t1, crossed);
    }
}

namespace {

/// What check_mis_weights saw.
struct MisCheck {
    int checked = 0;        ///< connections whose weights were checked
    int escaped = 0;        ///< of them s = 0 on an escaped camera vertex (infinite lights)
    int through_delta = 0;  ///< paths with a Dirac (specular) vertex
    int infinite = 0;       ///< paths whose emitter is an infinite light (dome, distant)
    int mixed_delta = 0;    ///< paths scattering through the Dirac lobe of a vertex that also
                            ///< has rough lobes (smooth clearcoat), inside the path
    int stale_delta = 0;    ///< connections at a vertex whose subpath went on through a
                            ///< Dirac lobe (the flag must not count: the path ends there)
};

/// For sampled camera and light subpaths, every connection with a contribution: the
/// production weight function evaluated on the path as every strategy would have made it
/// sums to 1 and the weight from the subpaths as sampled is the same. s = 0 on an escaped
/// camera vertex is checked once per infinite light that it sees (each is its own
/// emitter with its own weight, as BdptTracer::connect weights it).
MisCheck check_mis_weights(const Scene& s, uint32_t stream, const std::string& what, int samples) {
    const int W = 16, H = 16, depth = 6;
    Camera cam(s.camera_desc(), W, H);
    BdptTracer tr(s, cam, W, H, depth);
    BdptWorkspace ws;
    ws.camera.resize(depth + 2);
    ws.light.resize(depth + 1);
    BdptCounters c;
    MisCheck m;
    auto expect_sum = [&](const std::vector<float>& w, float here, int sl, int t) {
        double sum = 0;
        for (float x : w) {
            EXPECT_TRUE(std::isfinite(x)) << what;
            EXPECT_GE(x, 0.f) << what;
            sum += x;
        }
        EXPECT_NEAR(sum, 1.0, 1e-3) << what << ": s " << sl << " t " << t;
        EXPECT_NEAR(here, w[size_t(sl)], 1e-3 * std::max(1.f, w[size_t(sl)]))
            << what << ": s " << sl << " t " << t;
        ++m.checked;
    };
    for (uint32_t i = 0; i < uint32_t(samples); ++i) {
        PixelStreamSampler sampler(99, i, stream);
        sampler.start_stream(0);
        Vec2 u = sampler.next2d();
        int nc = tr.generate_camera_subpath(Vec2(u.x * W, u.y * H), sampler, depth + 2, false,
                                            ws.camera.data(), c);
        sampler.start_stream(1);
        int nl = tr.generate_light_subpath(sampler, depth + 1, false, ws.light.data(), c);
        sampler.start_stream(2);
        for (int t = 1; t <= nc; ++t)
            for (int sl = 0; sl <= nl; ++sl) {
                if ((sl == 1 && t == 1) || sl + t < 2 || sl + t - 2 > depth) continue;
                bool delta = false, mixed = false;
                auto is_mixed = [](const PathVertex& v) { return v.delta && v.bsdf && v.bsdf->has_non_delta(); };
                for (int k = 0; k + 1 < t; ++k) {
                    delta = delta || ws.camera[size_t(k)].delta;
                    mixed = mixed || is_mixed(ws.camera[size_t(k)]);
                }
                for (int k = 0; k + 1 < sl; ++k) {
                    delta = delta || ws.light[size_t(k)].delta;
                    mixed = mixed || is_mixed(ws.light[size_t(k)]);
                }
                bool stale = ws.camera[size_t(t - 1)].delta || (sl > 0 && ws.light[size_t(sl - 1)].delta);
                const PathVertex& pt = ws.camera[size_t(t - 1)];
                if (sl == 0 && pt.infinite) {
                    for (uint32_t li : s.infinite_lights()) {
                        if (is_black(s.light(li).le_escape(-pt.w_inf))) continue;
                        std::vector<PathVertex> cv(ws.camera.begin(), ws.camera.begin() + t);
                        cv[size_t(t - 1)].light_index = int32_t(li);
                        PathVertex none;
                        float here = -1.f;
                        std::vector<float> w =
                            tr.strategy_weights(ws.light.data(), 0, cv.data(), t, none, &here);
                        expect_sum(w, here, 0, t);
                        ++m.escaped;
                        ++m.infinite;
                        m.through_delta += delta;
                        m.mixed_delta += mixed;
                    }
                    continue;
                }
                Vec2 pr;
                PathVertex sampled;
                Spectrum L = tr.connect(ws.light.data(), sl, ws.camera.data(), t, sampler, &pr, false,
                                        c, &sampled);
                if (is_black(L)) continue;
                float here = -1.f;
                std::vector<float> w =
                    tr.strategy_weights(ws.light.data(), sl, ws.camera.data(), t, sampled, &here);
                expect_sum(w, here, sl, t);
                m.through_delta += delta;
                m.mixed_delta += mixed;
                m.stale_delta += stale;
                m.infinite += (sl == 1 ? sampled.infinite : sl > 1 && ws.light[0].infinite);
            }
    }
    std::printf("[mis %s] %d connections checked: %d s = 0 on escaped vertices, %d through a "
                "Dirac vertex (%d a mixed one), %d from infinite lights, %d at a vertex whose "
                "subpath went on through a Dirac lobe\n",
                what.c_str(), m.checked, m.escaped, m.through_delta, m.mixed_delta, m.infinite,
                m.stale_delta);
    return m;
}

/// A floor with a smooth clearcoat over a rough base (Dirac and non-Dirac lobes at one
/// vertex), a white mirror ball (metallic 1, roughness 0: a Dirac reflection), a diffuse
/// ball, a small smooth glass ball; a disk light, a uniform dome and a delta distant light
/// (angle 0).
void mirror_scene(Scene& s) {
    Material floor{Spectrum(0.6f, 0.55f, 0.5f), Spectrum(0.f)};
    Material mirror;
    mirror.preview = true;
    mirror.diffuse = Spectrum(1.f);
    mirror.metallic = 1.f;
    mirror.roughness = 0.f;
    Material coat;
    coat.preview = true;
    coat.diffuse = Spectrum(0.3f, 0.5f, 0.7f);
    coat.roughness = 0.5f;
    coat.clearcoat = 1.f;
    coat.clearcoat_roughness = 0.f;
    Material glass;
    glass.preview = true;
    glass.diffuse = Spectrum(0.f);
    glass.opacity = 0.f;
    glass.ior = 1.5f;
    glass.roughness = 0.f;
    s.set_materials({floor, mirror, coat, glass});
    s.add_instance(s.add_mesh("/floor", quad_mesh(Vec3(0.f), Vec3(2, 0, 0), Vec3(0, 0, -2), 2)), Mat4());
    s.add_instance(s.add_mesh("/mirror", sphere_mesh(0.35f, 16, 32, 1)), Mat4::translate(-0.45, 0.36, 0));
    s.add_instance(s.add_mesh("/ball", sphere_mesh(0.3f, 16, 32, 0)), Mat4::translate(0.45, 0.31, -0.2));
    s.add_instance(s.add_mesh("/glass", sphere_mesh(0.2f, 16, 32, 3)), Mat4::translate(0.1, 0.21, 0.45));
    LightDesc disk;
    disk.kind = LightDesc::Kind::disk;
    disk.transform = Mat4::translate(0.2, 1.5, 0.3) * Mat4::rotate(-90, 1, 0, 0);
    disk.radius = 0.3f;
    disk.radiance = Spectrum(10.f);
    s.add_light(disk);
    LightDesc dome;
    dome.kind = LightDesc::Kind::dome;
    dome.radiance = Spectrum(0.5f, 0.6f, 0.8f);
    s.add_light(dome);
    LightDesc sun;
    sun.kind = LightDesc::Kind::distant;
    sun.angle = 0.f;
    sun.radiance = Spectrum(3.f);
    sun.transform = Mat4::rotate(-60, 1, 0.4, 0);
    s.add_light(sun);
    s.set_camera(camera_at(Mat4::translate(0, 1.2, 1.9) * Mat4::rotate(-30, 1, 0, 0), 22.f, 36.f));
    s.commit();
}

/// The glass caustic scene under a uniform dome and a distant light with a 5 degree cone
/// (an infinite light that s = 0 can hit): escaped paths through Dirac refractions.
void glass_dome_scene(Scene& s) {
    glass_scene(s);
    s.clear_lights();
    LightDesc dome;
    dome.kind = LightDesc::Kind::dome;
    dome.radiance = Spectrum(0.8f, 0.9f, 1.f);
    s.add_light(dome);
    LightDesc sun;
    sun.kind = LightDesc::Kind::distant;
    sun.angle = 5.f;
    sun.radiance = Spectrum(200.f);
    sun.transform = Mat4::rotate(-30, 1, 0.2, 0);
    s.add_light(sun);
    s.commit();
}

}  // namespace

TEST(Bdpt, MisWeightsSumToOneDiracDomeDistant) {
    // Smooth glass and mirror (Dirac) vertices, a mixed Dirac / rough vertex (smooth
    // clearcoat), s = 0 on escaped vertices (dome; distant light with a cone), a delta
    // distant light (no s = 0), and the dome + sun scene of AgreesWithPtDomeAndSun.
    {
        Scene s;
        glass_scene(s);
        MisCheck m = check_mis_weights(s, 10, "glass + sphere light", 1000);
        EXPECT_GT(m.checked, 300);
        EXPECT_GT(m.through_delta, 50);
    }
    {
        Scene s;
        mirror_scene(s);
        MisCheck m = check_mis_weights(s, 11, "mirror + clearcoat + glass, disk + dome + delta sun", 1500);
        EXPECT_GT(m.checked, 300);
        EXPECT_GT(m.through_delta, 50);
        EXPECT_GT(m.mixed_delta, 10);
        EXPECT_GT(m.stale_delta, 10);
        EXPECT_GT(m.escaped, 50);
        EXPECT_GT(m.infinite, 100);
    }
    {
        Scene s;
        glass_dome_scene(s);
        MisCheck m = check_mis_weights(s, 12, "glass under dome + 5 degree sun", 600);
        EXPECT_GT(m.checked, 300);
        EXPECT_GT(m.through_delta, 50);
        EXPECT_GT(m.escaped, 50);
    }
    {
        Scene s;
        dome_scene(s);
        MisCheck m = check_mis_weights(s, 13, "dome + 5 degree sun", 400);
        EXPECT_GT(m.checked, 300);
        EXPECT_GT(m.escaped, 50);
        EXPECT_GT(m.infinite, 100);
    }
}

// ---- each strategy on its own --------------------------------------------------------------

TEST(Bdpt, ResumableStrategyIsEvaluateStrategyBitForBit) {
    // begin_strategy / resume_strategy answered by Scene::intersect and
    // Scene::transmittance (as coherent MLT's lanes are, with refined hits) give
    // evaluate_strategy's contribution, film position and ray counts exactly, weighted
    // and unweighted, on a scene with pass-through surfaces, a point light and emitters.
    Scene s;
    pass_through_box(s);
    const int W = 16, H = 16, max_depth = 5;
    const Camera cam(s.camera_desc(), W, H);
    const BdptTracer tr(s, cam, W, H, max_depth);
    BdptWorkspace ws_a, ws_b;
    int nonzero = 0;
    for (uint32_t i = 0; i < 3000; ++i) {
        const int depth = int(i % uint32_t(max_depth + 1));
        const int sl = int((i / 7) % uint32_t(depth + 2)), tl = depth + 2 - sl;
        const bool mis = i % 5 != 0;
        PixelStreamSampler a(11, i, 0), b(11, i, 0);
        BdptCounters ca, cb;
        Vec2 pa;
        const Spectrum la = tr.evaluate_strategy(depth, sl, tl, a, ws_a, &pa, ca, mis);
        BdptStrategyLane lane;
        BdptQuery q = tr.begin_strategy(lane, depth, sl, tl, b, ws_b, mis);
        while (q != BdptQuery::none) {
            if (q == BdptQuery::intersect) {
                q = tr.resume_strategy(lane, s.intersect(lane.walk.ray));
            } else {
                float pass_pdf = 1.f;
                const float t = s.transmittance(lane.conn.shadow, &pass_pdf);
                q = tr.resume_strategy(lane, t, pass_pdf);
            }
        }
        cb += lane.counters;
        ASSERT_EQ(std::memcmp(&la, &lane.result, sizeof(Spectrum)), 0)
            << "sample " << i << " (" << sl << ", " << tl << "): " << la.x << " vs " << lane.result.x;
        if (!(sl == 1 && tl == 1)) {
            EXPECT_EQ(pa.x, lane.p_raster.x) << i;
            EXPECT_EQ(pa.y, lane.p_raster.y) << i;
        }
        EXPECT_EQ(ca.rays, cb.rays) << i;
        EXPECT_EQ(ca.shadow_rays, cb.shadow_rays) << i;
        EXPECT_EQ(ca.samples, cb.samples) << i;
        nonzero += luminance(la) > 0.f ? 1 : 0;
    }
    EXPECT_GT(nonzero, 300);
}

TEST(Bdpt, UnweightedStrategiesAgreeWithMis) {
    // Depth 2 (paths camera - 2 scattering vertices - light) in the Cornell box: every
    // strategy (s, 4 - s), s = 0..3, alone estimates the image mean of that path length;
    // so does the MIS sum of all of them. z-tests of each against the MIS estimate
    // (4 comparisons, 1e-3 overall).
    Scene s;
    cornell(s);
    const int W = 16, H = 16, depth = 2;
    Camera cam(s.camera_desc(), W, H);
    BdptTracer tr(s, cam, W, H, depth);
    BdptWorkspace ws;
    BdptCounters c;
    const uint32_t N = 200000;
    auto estimate = [&](int sl, bool mis, uint32_t stream) {
        double sum = 0, sum2 = 0;
        for (uint32_t i = 0; i < N; ++i) {
            PixelStreamSampler sampler(5, i, stream);
            Vec2 pr;
            double v;
            if (sl < 0) {  // MIS: all strategies of this depth on the same sample
                Spectrum tot(0.f);
                for (int k = 0; k <= depth + 1; ++k) {
                    PixelStreamSampler sk(5, i, stream * 16 + uint32_t(k));
                    tot += tr.evaluate_strategy(depth, k, depth + 2 - k, sk, ws, &pr, c);
                }
                v = luminance(tot);
            } else {
                Spectrum L = mis ? tr.evaluate_strategy(depth, sl, depth + 2 - sl, sampler, ws, &pr, c)
                                 : tr.evaluate_strategy_unweighted(depth, sl, depth + 2 - sl,
                                                                   sampler, ws, &pr, c);
                v = luminance(L);
            }
            sum += v;
            sum2 += v * v;
        }
        double m = sum / N;
        double var = (sum2 / N - m * m) / (N - 1);
        return std::make_pair(m, std::sqrt(std::max(0.0, var)));
    };
    auto ref = estimate(-1, true, 1000);
    double z = z_for(1e-3 / 4);
    for (int sl = 0; sl <= depth + 1; ++sl) {
        auto e = estimate(sl, false, 100 + uint32_t(sl));
        double se = std::sqrt(e.second * e.second + ref.second * ref.second);
        std::printf("strategy s=%d t=%d: %.5f +- %.5f (MIS %.5f +- %.5f)\n", sl, depth + 2 - sl,
                    e.first, e.second, ref.first, ref.second);
        EXPECT_GT(e.first, 0.0);
        EXPECT_LT(std::fabs(e.first - ref.first), z * se) << "strategy s=" << sl;
    }
}

// ---- PT and BDPT agree ------------------------------------------------------------------------

TEST(Bdpt, AgreesWithPtCornell) {
    // Means resolved to ~1% (per-channel standard errors; the old 1% claim at 256 / 64
    // spp rested on the channels-independent standard error: really ~1.7%).
    // The one-pixel box: the spp were sized for its per-pixel variance (the gaussian's
    // pixels see their neighbourhood: ~20 % more variance here); the other scenes below
    // check the agreement under the default gaussian.
    expect_pt_bdpt_agree(cornell, 32, 32, 768, 256, "cornell", true, 0.01, "box");
}

TEST(Bdpt, AgreesWithPtSphereLight) {
    // A small bright sphere in a closed box is noisy for both; the image means are only
    // resolved to ~6% here (the block test carries the weight).
    expect_pt_bdpt_agree(sphere_light_box, 32, 32, 256, 96, "sphere light", false);
}

TEST(Bdpt, AgreesWithPtDomeAndSun) {
    expect_pt_bdpt_agree(dome_scene, 32, 32, 256, 96, "dome + distant");
}

TEST(Bdpt, AgreesWithPtThinLens) {
    // Depth of field: PT and BDPT (with t = 1 through the lens) see the same image.
    // Means to 2% (resolved to ~1.3%).
    expect_pt_bdpt_agree(cornell_lens, 32, 32, 384, 128, "cornell thin lens", true, 0.02);
}

TEST(Bdpt, AgreesWithPtPassThrough) {
    // Shadow rays and connections cross the cut-out and the ior-1 veil as
    // camera and BSDF rays do, with the crossings in the MIS densities.
    // Means to 2% (resolved to ~1.1%).
    expect_pt_bdpt_agree(pass_through_box, 32, 32, 384, 128, "pass-through", true, 0.02);
}

TEST(Bdpt, AgreesWithPtMotionBlur) {
    // Every ray of a BDPT sample carries the sample's shutter time; with time
    // 0 the block would sit at its start position in the BDPT image.
    // Means to 2% (resolved to ~1.35%).
    expect_pt_bdpt_agree(moving_block_box, 32, 32, 384, 128, "motion blur", true, 0.02);
}

TEST(Bdpt, AgreesWithPtGlassCaustic) {
    // Smooth-glass caustic: BDPT gets it from light tracing (t = 1), PT from BSDF
    // sampling through two Dirac refractions into the sphere light.
    // Means to 2% (resolved to ~1.4%; 1% would take twice the samples).
    expect_pt_bdpt_agree(glass_scene, 32, 32, 3072, 384, "glass caustic", true, 0.02);
}

// ---- furnace ------------------------------------------------------------------------------

TEST(Bdpt, ClosedFurnace) {
    // Camera inside a closed cube of albedo a emitting Le: L = Le / (1 - a); z < 4.5
    // per channel (3 checks, two-sided 2e-5 total).
    Scene s;
    s.set_materials({Material{Spectrum(0.5f), Spectrum(1.f)}});
    uint32_t m = s.add_mesh("/furnace", cube_mesh(1.f));
    s.add_instance(m, Mat4::rotate(20, 1, 1, 0));
    s.set_camera(camera_at(Mat4::translate(0.1, 0.2, 0.3) * Mat4::rotate(70, 0.2, 1, 0)));
    s.commit();
    RenderResult r = render(s, settings("bdpt", 24, 16, 16));
    EXPECT_EQ(r.stats.nan_samples, 0u);
    for (int c = 0; c < 3; ++c) {
        double sum = 0, var = 0;
        size_t n = size_t(r.width) * r.height;
        for (size_t i = 0; i < n; ++i) {
            sum += r.image[3 * i + c];
            var += r.variance[3 * i + c];
        }
        double mean = sum / n, se = std::sqrt(var) / n;
        EXPECT_LT(std::fabs(mean - 2.0), 4.5 * se + 1e-4) << "channel " << c << " mean " << mean;
        EXPECT_GT(std::fabs(mean - 2.05), 4.5 * se) << "the check could not fail";
    }
}

// ---- robustness ---------------------------------------------------------------------------

TEST(Bdpt, NoNanWithDiracAndDegenerateLights) {
    Scene s;
    s.set_materials({Material{Spectrum(0.8f), Spectrum(0.f)}});
    // Grazing geometry: a plane seen edge-on and a thin sliver.
    uint32_t floor = s.add_mesh("/floor", quad_mesh(Vec3(0.f), Vec3(2, 0, 0), Vec3(0, 0, -2)));
    s.add_instance(floor, Mat4());
    uint32_t sliver = s.add_mesh("/sliver", quad_mesh(Vec3(0, 0.5f, 0), Vec3(1, 0, 0), Vec3(0, 1e-7f, 0)));
    s.add_instance(sliver, Mat4());
    LightDesc point;
    point.kind = LightDesc::Kind::sphere;
    point.treat_as_point = true;
    point.radius = 0.1f;
    point.radiance = Spectrum(20.f);
    point.transform = Mat4::translate(0.3, 1, 0);
    s.add_light(point);
    LightDesc sun;
    sun.kind = LightDesc::Kind::distant;
    sun.angle = 0.f;
    sun.radiance = Spectrum(2.f);
    sun.transform = Mat4::rotate(-80, 1, 0, 0);
    s.add_light(sun);
    LightDesc zero_rect;
    zero_rect.kind = LightDesc::Kind::rect;
    zero_rect.width = 0.f;
    zero_rect.radiance = Spectrum(5.f);
    zero_rect.transform = Mat4::translate(0, 1, 0);
    s.add_light(zero_rect);
    LightDesc zero_sphere;
    zero_sphere.kind = LightDesc::Kind::sphere;
    zero_sphere.radius = 0.f;
    zero_sphere.radiance = Spectrum(5.f);
    s.add_light(zero_sphere);
    s.set_camera(camera_at(Mat4::translate(0, 1e-4, 1.5), 18.f, 36.f));
    s.commit();
    RenderResult r = render(s, settings("bdpt", 32, 24, 8));
    EXPECT_EQ(r.stats.nan_samples, 0u);
    for (float v : r.image) ASSERT_TRUE(std::isfinite(v));
    EXPECT_GT(image_mean(r), 0.0);
    EXPECT_GT(r.stats.splats, 0u);
}

TEST(Bdpt, DeterministicAcrossThreadCounts) {
    Scene s;
    sphere_light_box(s);
    RenderSettings st = settings("bdpt", 40, 24, 4);
    st.threads = 1;
    RenderResult a = render(s, st);
    st.threads = 2;
    RenderResult b = render(s, st);
    EXPECT_EQ(std::memcmp(a.image.data(), b.image.data(), a.image.size() * sizeof(float)), 0);
    EXPECT_EQ(std::memcmp(a.variance.data(), b.variance.data(), a.variance.size() * sizeof(float)), 0);
    EXPECT_EQ(a.stats.rays, b.stats.rays);
    EXPECT_EQ(a.stats.splats, b.stats.splats);
    st.seed = 8;
    RenderResult c = render(s, st);
    EXPECT_NE(std::memcmp(a.image.data(), c.image.data(), a.image.size() * sizeof(float)), 0);
}

