// Path tracer: determinism over thread counts, furnace and analytic scenes (checked
// against a confidence interval from the film's own variance), no NaN on degenerate
// input, settings errors, cancellation.
#include "test_util.h"

#include "integrators/common/render.h"
#include "util/error.h"

#include <gtest/gtest.h>

#include <cstring>

using namespace cmlt;
using namespace cmlt::test;

namespace {

/// Image mean of one channel and its standard error (pixels are independent).
struct Estimate {
    double mean = 0, stderr_ = 0;
};
Estimate image_mean(const RenderResult& r, int channel) {
    double sum = 0, var = 0;
    size_t n = size_t(r.width) * r.height;
    for (size_t i = 0; i < n; ++i) {
        sum += r.image[3 * i + channel];
        var += r.variance[3 * i + channel];
    }
    return {sum / n, std::sqrt(var) / n};
}

/// |mean - expected| within 4.5 standard errors (two-sided p ~ 7e-6 per check).
void expect_within_ci(const RenderResult& r, double expected, const char* what) {
    for (int c = 0; c < 3; ++c) {
        Estimate e = image_mean(r, c);
        EXPECT_GT(e.stderr_, 0.0) << what;
        EXPECT_LT(std::fabs(e.mean - expected), 4.5 * e.stderr_ + 1e-4 * expected)
            << what << ": channel " << c << " mean " << e.mean << " expected " << expected
            << " stderr " << e.stderr_;
    }
    EXPECT_EQ(r.stats.nan_samples, 0u) << what;
}

RenderSettings small(int spp, int depth = 64) {
    RenderSettings st;
    st.width = 32;
    st.height = 24;
    st.spp = spp;
    st.max_depth = depth;
    st.threads = 2;
    return st;
}

/// Camera inside a closed cube of albedo a emitting Le everywhere.
void furnace_scene(Scene& s, float albedo, float le) {
    s.set_materials({Material{Spectrum(albedo), Spectrum(le)}});
    uint32_t m = s.add_mesh("/furnace", cube_mesh(1.f));
    s.add_instance(m, Mat4::rotate(20, 1, 1, 0));
    s.set_camera(camera_at(Mat4::translate(0.1, 0.2, 0.3) * Mat4::rotate(70, 0.2, 1, 0)));
    s.commit();
}

/// A mixed scene for determinism: quads, a sphere light, an emissive quad, a dome.
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

}  // namespace

TEST(PathTracer, DeterministicAcrossThreadCounts) {
    Scene s;
    mixed_scene(s);
    RenderSettings st = small(8);
    st.seed = 42;
    st.threads = 1;
    RenderResult a = render(s, st);
    st.threads = 2;
    RenderResult b = render(s, st);
    ASSERT_EQ(a.image.size(), b.image.size());
    EXPECT_EQ(std::memcmp(a.image.data(), b.image.data(), a.image.size() * sizeof(float)), 0);
    EXPECT_EQ(std::memcmp(a.variance.data(), b.variance.data(), a.variance.size() * sizeof(float)), 0);
    EXPECT_EQ(a.stats.rays, b.stats.rays);
    st.seed = 43;
    RenderResult c = render(s, st);
    EXPECT_NE(std::memcmp(a.image.data(), c.image.data(), a.image.size() * sizeof(float)), 0);
    double m = image_mean(a, 1).mean;
    EXPECT_GT(m, 0.0);
    // the default gaussian (radius 1.5) traces the image and a one-pixel ring around it
    // (film/pass_splatter.h); the one-pixel box the image's pixels only
    EXPECT_EQ(a.stats.samples, uint64_t(34 * 26 * 8));
    EXPECT_EQ(a.stats.camera_rays, a.stats.samples);
    st.pixel_filter = "box";
    EXPECT_EQ(render(s, st).stats.samples, uint64_t(32 * 24 * 8));
    EXPECT_GT(a.stats.shadow_rays, 0u);
}

TEST(PathTracer, FurnaceInfiniteDepth) {
    // L = Le / (1 - a) with Russian roulette ending the paths.
    Scene s;
    furnace_scene(s, 0.5f, 1.f);
    expect_within_ci(render(s, small(64)), 2.0, "furnace a=0.5");
}

TEST(PathTracer, FurnaceTruncatedSeries) {
    // max_depth = n: L = Le (1 + a + ... + a^n).
    for (int depth : {1, 3}) {
        Scene s;
        furnace_scene(s, 0.8f, 0.5f);
        double expected = 0;
        for (int k = 0; k <= depth; ++k) expected += 0.5 * std::pow(0.8, k);
        expect_within_ci(render(s, small(16, depth)), expected, depth == 1 ? "depth 1" : "depth 3");
    }
}

TEST(PathTracer, FurnaceDetectsAWrongAnswer) {
    // The check itself can fail: the same render is far from a wrong expectation.
    Scene s;
    furnace_scene(s, 0.5f, 1.f);
    RenderResult r = render(s, small(16));
    Estimate e = image_mean(r, 0);
    EXPECT_GT(std::fabs(e.mean - 2.05), 4.5 * e.stderr_);
}

TEST(PathTracer, DiffusePlaneUnderDome) {
    // Irradiance pi L from the upper hemisphere; outgoing radiance a L (max_depth 1).
    Scene s;
    s.set_materials({Material{Spectrum(0.6f), Spectrum(0.f)}});
    uint32_t m = s.add_mesh("/plane", quad_mesh(Vec3(0.f), Vec3(1000, 0, 0), Vec3(0, 0, -1000)));
    s.add_instance(m, Mat4());
    LightDesc dome;
    dome.kind = LightDesc::Kind::dome;
    dome.radiance = Spectrum(2.f);
    s.add_light(dome);
    s.set_camera(camera_at(Mat4::translate(0, 1, 0) * Mat4::rotate(-60, 1, 0, 0)));
    s.commit();
    expect_within_ci(render(s, small(16, 1)), 1.2, "plane under dome");
}

/// A diffuse plane (albedo 0.5) at y = 0 seen in a tiny window around the origin from
/// the side; direct lighting only. Expected outgoing radiance is a E / pi.
void lit_plane_scene(Scene& s, const LightDesc& light) {
    s.set_materials({Material{Spectrum(0.5f), Spectrum(0.f)}});
    uint32_t m = s.add_mesh("/plane", quad_mesh(Vec3(0.f), Vec3(10, 0, 0), Vec3(0, 0, -10)));
    s.add_instance(m, Mat4());
    s.add_light(light);
    Mat4 cam = Mat4::translate(3, 1, 0) * Mat4::rotate(90, 0, 1, 0) * Mat4::rotate(-18.4349, 1, 0, 0);
    s.set_camera(camera_at(cam, 1000.f, 1.f));
    s.commit();
}

LightDesc light_above(LightDesc::Kind kind) {
    LightDesc d;
    d.kind = kind;
    d.radiance = Spectrum(4.f);
    d.transform = Mat4::translate(0, 1, 0) * Mat4::rotate(-90, 1, 0, 0);  // local -Z -> world -Y
    return d;
}

TEST(PathTracer, DiskLightOnAxis) {
    // E = pi L R^2 / (h^2 + R^2).
    LightDesc d = light_above(LightDesc::Kind::disk);
    d.radius = 0.5f;
    Scene s;
    lit_plane_scene(s, d);
    expect_within_ci(render(s, small(64, 1)), 0.5 * 4.0 * 0.25 / 1.25, "disk light on axis");
}

TEST(PathTracer, RectLightOnAxis) {
    // Square of side 1 at height 1: form factor 4 * (1/2pi) * 2 a/sqrt(1+a^2) atan(a/sqrt(1+a^2)), a = 1/2.
    LightDesc d = light_above(LightDesc::Kind::rect);
    Scene s;
    lit_plane_scene(s, d);
    double a = 0.5, q = a / std::sqrt(1 + a * a);
    double F = 4 * (2 * q * std::atan(q)) / (2 * M_PI);
    expect_within_ci(render(s, small(64, 1)), 0.5 * 4.0 * F, "rect light on axis");
}

TEST(PathTracer, SphereLightOnAxis) {
    // E = pi L sin^2(alpha), sin(alpha) = r / d.
    LightDesc d = light_above(LightDesc::Kind::sphere);
    d.radius = 0.5f;
    Scene s;
    lit_plane_scene(s, d);
    expect_within_ci(render(s, small(64, 1)), 0.5 * 4.0 * 0.25, "sphere light on axis");
}

TEST(PathTracer, DistantLightConeAndDelta) {
    // Cone of angular diameter 20 deg straight overhead: E = pi L sin^2(10 deg).
    LightDesc d = light_above(LightDesc::Kind::distant);
    d.transform = Mat4::rotate(-90, 1, 0, 0);  // direction to the light: +Y
    d.angle = 20.f;
    Scene s;
    lit_plane_scene(s, d);
    double s10 = std::sin(10 * M_PI / 180);
    expect_within_ci(render(s, small(64, 1)), 0.5 * 4.0 * s10 * s10, "distant cone");
    // Delta (angle 0), 60 degrees from the normal: radiance = a E cos / pi, exact.
    d.angle = 0.f;
    d.transform = Mat4::rotate(-30, 1, 0, 0);
    Scene s2;
    lit_plane_scene(s2, d);
    RenderSettings st = small(4, 1);
    st.pixel_filter = "box";  // exact per sample: weight 1 (a tabulated filter's f/pdf is 1 to ~1e-3)
    RenderResult r = render(s2, st);
    double expected = 0.5 * 4.0 * 0.5 / M_PI;
    for (float v : r.image) ASSERT_NEAR(v, expected, 1e-4 * expected);
}

TEST(PathTracer, NoNaNOnDegenerateInput) {
    Scene s;
    s.set_materials({Material{Spectrum(0.7f), Spectrum(0.f)}, Material{Spectrum(0.5f), Spectrum(3.f)}});
    // Degenerate triangles (zero area, collinear, repeated index), also emissive.
    uint32_t bad = s.add_mesh("/bad", make_mesh_data({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0), Vec3(0, 1, 0)},
                                                     {0, 1, 2, 0, 0, 3, 1, 1, 1, 0, 1, 3}, {1, 0, 1, 0}));
    // Zero-length shading normals on one vertex.
    uint32_t nq = s.add_mesh("/normals", make_mesh_data({Vec3(-1, 0, -1), Vec3(1, 0, -1), Vec3(1, 0, 1), Vec3(-1, 0, 1)},
                                                        {0, 2, 1, 0, 3, 2}, {},
                                                        {Vec3(0.f), Vec3(0, 1, 0), Vec3(0, 1, 0), Vec3(0, -1, 0)}));
    s.add_instance(bad, Mat4());
    s.add_instance(nq, Mat4::scale(5, 1, 5));
    for (int kind = 0; kind < 4; ++kind) {
        LightDesc d;
        d.transform = Mat4::translate(0, 0.5, 0);
        d.radiance = Spectrum(1.f);
        d.width = 0.f;
        d.radius = 0.f;
        d.angle = 0.f;
        d.kind = kind == 0 ? LightDesc::Kind::rect : kind == 1 ? LightDesc::Kind::disk
                : kind == 2 ? LightDesc::Kind::sphere : LightDesc::Kind::distant;
        s.add_light(d);
    }
    LightDesc pt;
    pt.kind = LightDesc::Kind::sphere;
    pt.treat_as_point = true;
    pt.radius = 0.f;
    s.add_light(pt);
    // Camera in the plane of the quad: grazing rays.
    s.set_camera(camera_at(Mat4::translate(0, 0, 4), 18.f, 36.f));
    s.commit();
    RenderResult r = render(s, small(8));
    EXPECT_EQ(r.stats.nan_samples, 0u);
    for (float v : r.image) ASSERT_TRUE(std::isfinite(v));
    for (float v : r.variance) ASSERT_TRUE(std::isfinite(v));
}

TEST(Render, SettingsErrorsNameTheField) {
    Scene s;
    furnace_scene(s, 0.5f, 1.f);
    auto msg = [&](RenderSettings st) {
        try {
            render(s, st);
        } catch (const SettingsError& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    RenderSettings st = small(1);
    st.width = 0;
    EXPECT_NE(msg(st).find("width"), std::string::npos);
    st = small(1);
    st.spp = 0;
    EXPECT_NE(msg(st).find("spp"), std::string::npos);
    st = small(1);
    st.max_depth = 0;
    EXPECT_NE(msg(st).find("max_depth"), std::string::npos);
    st = small(1);
    st.integrator = "bogus";
    EXPECT_NE(msg(st).find("integrator"), std::string::npos);
    Scene nocam;
    EXPECT_THROW(render(nocam, small(1)), SceneError);
}

TEST(Render, ProgressAndCancel) {
    Scene s;
    furnace_scene(s, 0.5f, 1.f);
    std::vector<std::pair<uint64_t, uint64_t>> calls;
    RenderResult full = render(s, small(32), [&](uint64_t d, uint64_t t) {
        calls.push_back({d, t});
        return true;
    });
    EXPECT_FALSE(full.cancelled);
    ASSERT_FALSE(calls.empty());
    EXPECT_EQ(calls.back(), (std::pair<uint64_t, uint64_t>{32, 32}));
    int n = 0;
    RenderResult cut = render(s, small(32), [&](uint64_t, uint64_t) { return ++n < 2; });
    EXPECT_TRUE(cut.cancelled);
    EXPECT_LT(cut.stats.samples, full.stats.samples);
    EXPECT_EQ(n, 2);
}
