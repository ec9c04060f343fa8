// Bidirectional path tracing: for sampled camera and light subpaths, the MIS weights of
// every connection sum to 1 over the strategies that could have made its path, and the
// weight from the subpaths as sampled is the same (area and sphere lights, a thin lens,
// pass-through surfaces, motion blur, Dirac vertices, dome and distant lights).
// The checks are deterministic (fixed seeds); sums and weights agree to 1e-3 (float
// rounding along paths of up to 6 bounces).
#include "bdpt/bdpt_scenes.h"
#include "test_scenes.h"
#include "test_util.h"

#include "integrators/bdpt/bdpt_tracer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

using namespace cmlt;
using namespace cmlt::test;

TEST(Bdpt, MisWeightsSumToOne) {
    // Sample camera and light subpaths; for every connection with a contribution, the
    // production weight function evaluated on the path as every strategy would have
    // made it sums to 1, and the weight from the subpaths as sampled is the same.
    // Scenes 3-5: light tracing (t = 1) through a thin lens; cut-out and
    // ior-1 pass-through surfaces crossed by subpaths and connections (their crossing
    // probabilities enter the densities); motion blur (one shutter time per sample).
    // Each scene twice: without and with the (1, 1) strategy (a light point connected to
    // the lens, which then shares the depth-0 paths with (0, 2)).
    int checked_11 = 0;
    for (int run = 0; run < 12; ++run) {
        const int scene_kind = run % 6;
        const bool direct = run >= 6;
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
        std::vector<uint32_t> every_light;
        for (uint32_t li = 0; li < uint32_t(s.light_count()); ++li) every_light.push_back(li);
        if (direct) tr.set_direct_light_tracing(every_light);
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
                    if ((sl == 1 && t == 1 && !direct) || sl + t < 2 || sl + t - 2 > 6) continue;
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
                    checked_11 += sl == 1 && t == 1;
                }
        }
        EXPECT_GT(checked, 200) << "scene " << scene_kind;
        // Light tracing reaches the camera, through the lens too.
        EXPECT_GT(checked_t1, 20) << "scene " << scene_kind;
        // The walks did cross the pass-through surfaces with probability < 1.
        if (scene_kind == 4) { EXPECT_GT(crossed, 20); }
        std::printf("scene %d%s: %d connections checked, %d of them t = 1, %d vertices after "
                    "crossings\n", scene_kind, direct ? " with (1, 1)" : "", checked, checked_t1,
                    crossed);
    }
    // (1, 1) made paths (lights in view) and its weights were checked with (0, 2)'s.
    EXPECT_GT(checked_11, 20);
    std::printf("(1, 1): %d connections checked\n", checked_11);
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
    s.set_materials({floor, mirror, coat, smooth_glass()});
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
    add_dome_and_sun(s, Spectrum(0.5f, 0.6f, 0.8f), Spectrum(3.f), 0.f, Mat4::rotate(-60, 1, 0.4, 0));
    s.set_camera(camera_at(Mat4::translate(0, 1.2, 1.9) * Mat4::rotate(-30, 1, 0, 0), 22.f, 36.f));
    s.commit();
}

/// The glass caustic scene under a uniform dome and a distant light with a 5 degree cone
/// (an infinite light that s = 0 can hit): escaped paths through Dirac refractions.
void glass_dome_scene(Scene& s) {
    glass_scene(s);
    s.clear_lights();
    add_dome_and_sun(s, Spectrum(0.8f, 0.9f, 1.f), Spectrum(200.f), 5.f, Mat4::rotate(-30, 1, 0.2, 0));
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
