// DomeLight with a lat-long HDR texture: the UsdLux / OpenEXR direction <-> st convention,
// the 2-D piecewise-constant distribution, chi-square of sample_li against pdf_li, pdf
// consistency, and a furnace-style check (a Lambert plane, max_depth 1, under an HDR
// dome must show albedo/pi times the cosine-weighted integral of the environment,
// computed here by quadrature of the texture with the test's own mapping) for PT and
// BDPT; the escaped-ray radiance and density in one call equal the two calls. Also the
// textured RectLight.
//
// False alarms: chi-square tests at alpha = 1e-3 / 4 each (4 in this file); the render
// checks at |z| < 4.5 (two-sided 7e-6 each, 12 checks).
#include "chi2.h"
#include "test_util.h"

#include "integrators/common/render.h"
#include "lights/area_lights.h"
#include "lights/dome_light.h"
#include "sampling/piecewise_constant_2d.h"
#include "sampling/warp.h"
#include "textures/texture.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace cmlt;
using namespace cmlt::test;

namespace {

constexpr double k_alpha = 1e-3 / 4;

/// The convention written out independently of the implementation: st -> light-space
/// direction (UsdLux DomeLight = OpenEXR latlong, +Y up, s = 0.5 -> +Z, s = 0.25 -> +X).
Vec3 test_dir(double s, double t) {
    double phi = M_PI * (1 - 2 * s), theta = M_PI * (1 - t);
    return Vec3(float(std::sin(theta) * std::sin(phi)), float(std::cos(theta)),
                float(std::sin(theta) * std::cos(phi)));
}

/// An HDR sky: a gradient (bright horizon, blue zenith, dark ground) and a small bright
/// Gaussian "sun" at s0, t0. Row 0 is the top (+Y).
std::shared_ptr<std::vector<float>> make_sky(int w, int h, double s0, double t0, double sun) {
    auto img = std::make_shared<std::vector<float>>(size_t(w) * h * 3);
    Vec3 sd = test_dir(s0, t0);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            double s = (x + 0.5) / w, t = 1 - (y + 0.5) / h;
            Vec3 d = test_dir(s, t);
            double up = d.y;
            double c = std::max(-1.0, std::min(1.0, double(dot(d, sd))));
            double blob = sun * std::exp(-(1 - c) / 0.002);
            float* p = &(*img)[(size_t(y) * w + x) * 3];
            if (up >= 0) {
                p[0] = float(0.3 + 0.5 * (1 - up) + blob);
                p[1] = float(0.45 + 0.4 * (1 - up) + blob);
                p[2] = float(0.9 + 0.1 * (1 - up) + 0.9 * blob);
            } else {
                p[0] = p[1] = p[2] = float(0.05 + blob);
            }
        }
    return img;
}

TextureDesc texture_desc(const std::shared_ptr<std::vector<float>>& img, int w, int h) {
    TextureDesc d;
    d.data = img->data();
    d.width = w;
    d.height = h;
    d.channels = 3;
    d.wrap_s = WrapMode::repeat;
    d.wrap_t = WrapMode::clamp;
    d.owner = img;
    return d;
}

}  // namespace

TEST(Dome, LatLongConvention) {
    float st_;
    // st (0.5, 0.5) -> +Z, (0.25, 0.5) -> +X, (0.75, 0.5) -> -X, t = 1 -> +Y, t = 0 -> -Y.
    Vec3 z = dome_st_to_direction(Vec2(0.5f, 0.5f), &st_);
    EXPECT_NEAR(z.z, 1.f, 1e-6f);
    Vec3 x = dome_st_to_direction(Vec2(0.25f, 0.5f), &st_);
    EXPECT_NEAR(x.x, 1.f, 1e-6f);
    Vec3 mx = dome_st_to_direction(Vec2(0.75f, 0.5f), &st_);
    EXPECT_NEAR(mx.x, -1.f, 1e-6f);
    EXPECT_NEAR(dome_st_to_direction(Vec2(0.3f, 1.f), &st_).y, 1.f, 1e-6f);
    EXPECT_NEAR(dome_st_to_direction(Vec2(0.3f, 0.f), &st_).y, -1.f, 1e-6f);
    for (uint32_t i = 0; i < 1000; ++i) {
        Vec2 u = uniform2(300, i);
        Vec3 d = test_dir(u.x, u.y);
        Vec3 e = dome_st_to_direction(u, &st_);
        EXPECT_NEAR(length(d - e), 0.f, 1e-5f);
        Vec2 back = dome_direction_to_st(d);
        EXPECT_NEAR(back.y, u.y, 1e-4f);
        double ds = std::fabs(back.x - u.x);
        EXPECT_LT(std::min(ds, 1 - ds), 1e-4) << u.x << " " << back.x;
    }
}

TEST(Dome, PiecewiseConstant2DChi2) {
    const int nx = 7, ny = 5;
    std::vector<float> w(nx * ny);
    for (int i = 0; i < nx * ny; ++i) w[size_t(i)] = float((i * 37) % 11);  // some zeros
    PiecewiseConstant2D dist(w, nx, ny);
    double total = 0;
    for (float v : w) total += v;
    const uint32_t n = 100000;
    std::vector<double> obs(nx * ny, 0.0), exp(nx * ny, 0.0);
    for (int i = 0; i < nx * ny; ++i) exp[size_t(i)] = n * w[size_t(i)] / total;
    for (uint32_t i = 0; i < n; ++i) {
        float pdf;
        Vec2 p = dist.sample(uniform2(301, i), &pdf);
        ASSERT_TRUE(p.x >= 0 && p.x < 1 && p.y >= 0 && p.y < 1);
        int cx = int(p.x * nx), cy = int(p.y * ny);
        ASSERT_GT(w[size_t(cy * nx + cx)], 0.f) << "sampled a zero-weight cell";
        EXPECT_NEAR(pdf, dist.pdf(p), 1e-5f * pdf);
        EXPECT_NEAR(pdf, w[size_t(cy * nx + cx)] * nx * ny / total, 1e-4f * pdf);
        obs[size_t(cy * nx + cx)] += 1;
    }
    Chi2Result r = chi2_test(obs, exp);
    EXPECT_TRUE(r.passed(k_alpha)) << r.message << "\n" << dump_table(obs, exp, nx);
    // Uniform fallback for all-zero weights.
    PiecewiseConstant2D zero(std::vector<float>(6, 0.f), 3, 2);
    float pdf;
    zero.sample(Vec2(0.3f, 0.8f), &pdf);
    EXPECT_NEAR(pdf, 1.f, 1e-6f);
}

TEST(Dome, SampleLiChi2AgainstPdf) {
    const int w = 64, h = 32;
    auto img = make_sky(w, h, 0.62, 0.78, 400.0);
    Texture tex(texture_desc(img, w, h), "sky");
    const double angle = 35;
    LightDesc d;
    d.kind = LightDesc::Kind::dome;
    d.radiance = Spectrum(1.5f, 1.f, 0.8f);
    d.transform = Mat4::rotate(angle, 0.3, 1, 0.2);
    Mat4 inv = Mat4::rotate(-angle, 0.3, 1, 0.2);
    d.texture_id = 0;
    DomeLight dome(d);
    dome.bind_texture(&tex);
    dome.preprocess(Vec3(0.f), 1.f);
    // Cells: 2 x 2 texel blocks of the light's own (s, v = 1 - t) domain; expected mass by
    // midpoint quadrature of pdf_li over world directions (the density times the
    // Jacobian 2 pi^2 sin(theta) is constant on a texel, so 2 x 2 points per texel are exact).
    const int cx = w / 2, cy = h / 2, q = 4;
    const uint32_t n = 400000;
    std::vector<double> exp(size_t(cx) * cy, 0.0), obs(size_t(cx) * cy, 0.0);
    double total = 0;
    for (int j = 0; j < cy; ++j)
        for (int i = 0; i < cx; ++i) {
            double m = 0;
            for (int b = 0; b < q; ++b)
                for (int a = 0; a < q; ++a) {
                    double s = (i + (a + 0.5) / q) / cx, v = (j + (b + 0.5) / q) / cy;
                    double theta = M_PI * v;
                    Vec3 wd = d.transform.transform_vector(test_dir(s, 1 - v));
                    m += dome.pdf_li(Vec3(0.f), normalize(wd)) * 2 * M_PI * M_PI *
                         std::sin(theta) / (double(cx) * cy * q * q);
                }
            exp[size_t(j) * cx + i] = m * n;
            total += m;
        }
    EXPECT_NEAR(total, 1.0, 1e-3) << "pdf_li does not integrate to 1 over the sphere";
    for (uint32_t k = 0; k < n; ++k) {
        LightSample ls = dome.sample_li(Vec3(0.f), uniform2(302, k));
        ASSERT_TRUE(ls.valid());
        ASSERT_TRUE(std::isinf(ls.dist));
        if (k < 2000) {
            EXPECT_NEAR(ls.pdf, dome.pdf_li(Vec3(0.f), ls.wi), 2e-3f * ls.pdf);
            Spectrum le = dome.le_escape(ls.wi);
            EXPECT_NEAR(ls.li.x, le.x, 1e-3f * le.x + 1e-6f);
        }
        Vec3 l = normalize(inv.transform_vector(ls.wi));
        double s = 0.5 - std::atan2(double(l.x), double(l.z)) / (2 * M_PI);
        if (s >= 1) s -= 1;
        if (s < 0) s += 1;
        double v = std::acos(std::max(-1.0, std::min(1.0, double(l.y)))) / M_PI;
        int i = std::min(cx - 1, int(s * cx)), j = std::min(cy - 1, int(v * cy));
        obs[size_t(j) * cx + i] += 1;
    }
    Chi2Result r = chi2_test(obs, exp);
    EXPECT_TRUE(r.passed(k_alpha)) << r.message;
    // Importance sampling: the sun cell gets far more than its uniform share.
    EXPECT_GT(dome.power(), 0.f);
}

TEST(Dome, TextureOrientationSeenByEscapingRays) {
    // One bright texel column at s ~ 0.25 must be seen along light-space +X.
    const int w = 16, h = 8;
    auto img = std::make_shared<std::vector<float>>(size_t(w) * h * 3, 0.1f);
    for (int y = 0; y < h; ++y)
        for (int c = 0; c < 3; ++c) (*img)[(size_t(y) * w + 3) * 3 + c] = 5.f;  // s in [3/16, 4/16)
    Texture tex(texture_desc(img, w, h), "col");
    LightDesc d;
    d.kind = LightDesc::Kind::dome;
    d.radiance = Spectrum(1.f);
    d.texture_id = 0;
    DomeLight dome(d);
    dome.bind_texture(&tex);
    Vec3 toward = test_dir(3.5 / 16, 0.5);
    EXPECT_GT(toward.x, 0.9f);
    EXPECT_NEAR(dome.le_escape(toward).x, 5.f, 1e-4f);
    EXPECT_NEAR(dome.le_escape(Vec3(-1, 0, 0)).x, 0.1f, 1e-4f);
    // The world +Y pole sees the top row.
    EXPECT_NEAR(dome.le_escape(Vec3(0, 1, 0)).x, 0.1f, 1e-4f);
}

TEST(Dome, EscapeRadianceAndPdfTogetherAreTheTwoCallsBitForBit) {
    // le_escape_pdf (path tracing's escaped rays: radiance and the MIS density from one
    // direction-to-texture mapping) against le_escape and pdf_li, textured and plain.
    const int w = 64, h = 32;
    auto img = make_sky(w, h, 0.3, 0.6, 200.0);
    Texture tex(texture_desc(img, w, h), "sky");
    for (bool textured : {true, false}) {
        LightDesc d;
        d.kind = LightDesc::Kind::dome;
        d.radiance = Spectrum(1.5f, 1.f, 0.8f);
        d.transform = Mat4::rotate(20, 0.2, 1, 0.4);
        d.texture_id = textured ? 0 : -1;
        DomeLight dome(d);
        if (textured) dome.bind_texture(&tex);
        dome.preprocess(Vec3(0.f), 1.f);
        for (uint32_t k = 0; k < 5000; ++k) {
            const Vec3 dir = square_to_uniform_sphere(uniform2(77, k));
            const Vec3 p(0.5f, -1.f, 2.f);
            float pdf = -1.f;
            const Spectrum both = dome.le_escape_pdf(dir, p, &pdf);
            const Spectrum le = dome.le_escape(dir);
            ASSERT_EQ(pdf, dome.pdf_li(p, dir)) << "direction " << k;
            ASSERT_TRUE(both.x == le.x && both.y == le.y && both.z == le.z) << "direction " << k;
            const Spectrum alone = dome.le_escape_pdf(dir, p, nullptr);  // no density asked
            ASSERT_TRUE(alone.x == le.x && alone.y == le.y && alone.z == le.z) << "direction " << k;
        }
    }
}

namespace {

/// Lambert plane y = 0 (albedo rho) seen straight down by an orthographic camera, under a
/// rotated HDR dome; returns the expected radiance rho/pi * int L cos over the upper
/// hemisphere (quadrature over world directions with the test's own mapping).
struct FurnaceScene {
    std::shared_ptr<std::vector<float>> img;
    Spectrum expected;
};

FurnaceScene furnace_scene(Scene& s) {
    const int w = 128, h = 64;
    FurnaceScene f;
    f.img = make_sky(w, h, 0.4, 0.85, 60.0);
    const float rho = 0.5f;
    s.set_materials({Material{Spectrum(rho), Spectrum(0.f)}});
    uint32_t m = s.add_mesh("/floor", quad_mesh(Vec3(0.f), Vec3(20, 0, 0), Vec3(0, 0, -20)));
    s.add_instance(m, Mat4());
    uint32_t tid = s.add_texture(texture_desc(f.img, w, h), "sky");
    LightDesc d;
    d.kind = LightDesc::Kind::dome;
    d.radiance = Spectrum(2.f, 1.5f, 1.f);
    d.transform = Mat4::rotate(25, 1, 0, 0.4);
    d.texture_id = int32_t(tid);
    s.add_light(d);
    CameraDesc cam = camera_at(Mat4::translate(0, 1, 0) * Mat4::rotate(-90, 1, 0, 0), 18.f, 20.f);
    cam.projection = CameraDesc::Projection::orthographic;
    s.set_camera(cam);
    s.commit();
    // Quadrature: z = cos(theta) in [0, 1], phi in [0, 2 pi); the light's texture at the
    // direction's st (independent mapping: inverse rotation, atan2, acos).
    Texture tex(texture_desc(f.img, w, h), "sky");
    Mat4 inv = Mat4::rotate(-25, 1, 0, 0.4);
    const int nz = 400, nphi = 800;
    double acc[3] = {0, 0, 0};
    for (int i = 0; i < nz; ++i)
        for (int j = 0; j < nphi; ++j) {
            double z = (i + 0.5) / nz, phi = 2 * M_PI * (j + 0.5) / nphi;
            double r = std::sqrt(std::max(0.0, 1 - z * z));
            Vec3 wd(float(r * std::cos(phi)), float(z), float(r * std::sin(phi)));  // world, +Y up
            Vec3 l = normalize(inv.transform_vector(wd));
            double st_s = 0.5 - std::atan2(double(l.x), double(l.z)) / (2 * M_PI);
            if (st_s < 0) st_s += 1;
            double st_t = 1 - std::acos(std::max(-1.0, std::min(1.0, double(l.y)))) / M_PI;
            Vec3 c = tex.eval(Vec2(float(st_s), float(st_t))).xyz();
            double wq = z * (1.0 / nz) * (2 * M_PI / nphi);
            acc[0] += c.x * wq;
            acc[1] += c.y * wq;
            acc[2] += c.z * wq;
        }
    f.expected = Spectrum(float(rho / M_PI * acc[0] * 2.0), float(rho / M_PI * acc[1] * 1.5),
                          float(rho / M_PI * acc[2] * 1.0));
    return f;
}

void expect_furnace(const char* integrator, int spp) {
    Scene s;
    FurnaceScene f = furnace_scene(s);
    RenderSettings st;
    st.width = 16;
    st.height = 16;
    st.spp = spp;
    st.max_depth = 1;
    st.threads = 2;
    st.seed = 5;
    st.integrator = integrator;
    RenderResult r = render(s, st);
    EXPECT_EQ(r.stats.nan_samples, 0u);
    size_t n = size_t(r.width) * r.height;
    for (int c = 0; c < 3; ++c) {
        double sum = 0, var = 0;
        for (size_t i = 0; i < n; ++i) {
            sum += r.image[3 * i + c];
            var += r.variance[3 * i + c];
        }
        double mean = sum / n, se = std::sqrt(var) / n;
        double want = c == 0 ? f.expected.x : c == 1 ? f.expected.y : f.expected.z;
        // |z| < 4.5 plus the quadrature's own error (~1e-3 relative).
        EXPECT_LT(std::fabs(mean - want), 4.5 * se + 2e-3 * want)
            << integrator << " channel " << c << " mean " << mean << " expected " << want
            << " stderr " << se;
        EXPECT_LT(se, 0.01 * want) << integrator << ": too noisy for a 1% check";
        std::printf("[dome furnace %s] channel %d: %.5f expected %.5f (stderr %.5f)\n",
                    integrator, c, mean, want, se);
    }
}

}  // namespace

TEST(Dome, FurnacePlanePt) { expect_furnace("pt", 1024); }
TEST(Dome, FurnacePlaneBdpt) { expect_furnace("bdpt", 1024); }

TEST(Dome, TexturedRectLight) {
    // A rect light textured half black / half white: half the power, radiance by side.
    const int w = 8, h = 8;
    auto img = std::make_shared<std::vector<float>>(size_t(w) * h * 3, 0.f);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w / 2; ++x)
            for (int c = 0; c < 3; ++c) (*img)[(size_t(y) * w + x) * 3 + c] = 1.f;  // s < 0.5
    TextureDesc td = texture_desc(img, w, h);
    td.wrap_s = WrapMode::clamp;
    Texture tex(td, "rect");
    LightDesc d;
    d.kind = LightDesc::Kind::rect;
    d.width = 2.f;
    d.height = 1.f;
    d.radiance = Spectrum(3.f);
    d.texture_id = 0;
    RectLight l(d);
    float p_plain = l.power();
    l.bind_texture(&tex);
    EXPECT_NEAR(l.power(), 0.5f * p_plain, 1e-4f * p_plain);
    // st (0, .) is at local +X: a ray from below (z < 0, travelling +Z) hitting x = +0.8
    // sees the white half; x = -0.8 the black half.
    float t;
    Spectrum le;
    ASSERT_TRUE(l.intersect(Ray(Vec3(0.8f, 0.f, -1.f), Vec3(0, 0, 1)), &t, &le));
    EXPECT_NEAR(le.x, 3.f, 1e-5f);
    ASSERT_TRUE(l.intersect(Ray(Vec3(-0.8f, 0.f, -1.f), Vec3(0, 0, 1)), &t, &le));
    EXPECT_NEAR(le.x, 0.f, 1e-5f);
    // sample_li / sample_le carry the texel at the sampled point.
    for (uint32_t i = 0; i < 200; ++i) {
        LightSample ls = l.sample_li(Vec3(0, 0, -2), uniform2(303, i));
        if (!ls.valid()) {
            EXPECT_LT(ls.p_light.x, 0.3f);
            continue;
        }
        Vec3 pl = ls.p_light;
        if (std::fabs(pl.x) > 0.3f) { EXPECT_NEAR(ls.li.x, pl.x > 0 ? 3.f : 0.f, 1e-5f); }
        LightLeSample le_s = l.sample_le(uniform2(304, i), uniform2(305, i));
        if (le_s.valid() && !is_black(le_s.le) && std::fabs(le_s.p.x) > 0.3f) {
            EXPECT_GT(le_s.p.x, 0.f);
        }
    }
}
