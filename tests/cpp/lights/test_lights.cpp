// Lights: sample_li / pdf_li consistency, pdfs integrate to 1 (solid angle checks),
// the sphere-cap sampler's chi-square test, one-sidedness, degenerate lights.
#include "chi2.h"
#include "test_util.h"

#include "lights/area_lights.h"
#include "lights/infinite_lights.h"
#include "lights/sphere_light.h"
#include "lights/triangle_light.h"
#include "math/frame.h"
#include "sampling/warp.h"

#include <gtest/gtest.h>

using namespace cmlt;
using namespace cmlt::test;

namespace {

constexpr double k_alpha = 1e-3 / 8;  // same family as test_sampling.cpp (Bonferroni)

LightDesc desc(LightDesc::Kind kind, const Mat4& xf) {
    LightDesc d;
    d.kind = kind;
    d.transform = xf;
    d.radiance = Spectrum(2.f, 3.f, 4.f);
    return d;
}

/// E[1/pdf] over light samples = solid angle of the light; also pdf_li == sample pdf.
/// Checked within 4.5 standard errors (plus float slack).
void expect_solid_angle(const Light& l, const Vec3& p, uint32_t stream, double omega, int n = 200000) {
    double sum = 0, sum2 = 0;
    for (int i = 0; i < n; ++i) {
        LightSample s = l.sample_li(p, uniform2(stream, uint32_t(i)));
        if (!s.valid()) continue;
        float pdf = l.pdf_li(p, s.wi);
        EXPECT_NEAR(pdf, s.pdf, 2e-3f * s.pdf) << "sample " << i;
        sum += 1.0 / s.pdf;
        sum2 += 1.0 / (double(s.pdf) * s.pdf);
    }
    double mean = sum / n, var = std::max(0.0, sum2 / n - mean * mean) / n;
    EXPECT_NEAR(mean, omega, 4.5 * std::sqrt(var) + 1e-5 * omega);
}

/// Integral of pdf_li over the sphere by uniform-sphere Monte Carlo.
double integrate_pdf(const Light& l, const Vec3& p, uint32_t stream, int n = 400000) {
    double sum = 0;
    for (int i = 0; i < n; ++i) sum += l.pdf_li(p, square_to_uniform_sphere(uniform2(stream, uint32_t(i))));
    return sum * 4 * M_PI / n;
}

}  // namespace

TEST(Lights, RectSolidAngleAndPdf) {
    // 2 x 1 rect at height 1 above the origin, emitting down (-Z local = -Z world).
    LightDesc d = desc(LightDesc::Kind::rect, Mat4::translate(0, 0, 1));
    d.width = 2.f;
    d.height = 1.f;
    RectLight l(d);
    Vec3 p(0.f);
    double a = 2, b = 1, h = 1;
    double omega = 4 * std::asin(a * b / std::sqrt((a * a + 4 * h * h) * (b * b + 4 * h * h)));
    expect_solid_angle(l, p, 100, omega);
    EXPECT_NEAR(integrate_pdf(l, p, 101), 1.0, 0.03);
    // One-sided: from above (behind) it is dark and invisible.
    EXPECT_FALSE(l.sample_li(Vec3(0, 0, 2), Vec2(0.5f, 0.5f)).valid());
    float t;
    Spectrum le;
    EXPECT_FALSE(l.intersect(Ray(Vec3(0, 0, 2), Vec3(0, 0, -1)), &t, &le));
    ASSERT_TRUE(l.intersect(Ray(Vec3(0, 0, 0), Vec3(0, 0, 1)), &t, &le));
    EXPECT_NEAR(t, 1.f, 1e-6f);
    EXPECT_EQ(le, Spectrum(2.f, 3.f, 4.f));
}

TEST(Lights, DiskSolidAngleAndPdf) {
    LightDesc d = desc(LightDesc::Kind::disk, Mat4::translate(0, 0, 2) * Mat4::rotate(180, 0, 1, 0));
    d.radius = 1.5f;  // rotated to emit toward +Z: the point must be above
    DiskLight l(d);
    Vec3 p(0, 0, 3);
    double R = 1.5, h = 1;
    double omega = 2 * M_PI * (1 - h / std::sqrt(h * h + R * R));
    expect_solid_angle(l, p, 102, omega);
    EXPECT_NEAR(integrate_pdf(l, p, 103), 1.0, 0.03);
    EXPECT_FALSE(l.sample_li(Vec3(0, 0, 0), Vec2(0.3f, 0.3f)).valid());
}

TEST(Lights, SphereCapSolidAngleAndChi2) {
    LightDesc d = desc(LightDesc::Kind::sphere, Mat4::translate(1, 2, 3));
    d.radius = 0.8f;
    SphereLight l(d);
    Vec3 p(0.f);
    float dist = std::sqrt(14.f);
    double cos_max = std::sqrt(1 - 0.64 / 14.0);
    double omega = 2 * M_PI * (1 - cos_max);
    expect_solid_angle(l, p, 104, omega);
    EXPECT_NEAR(integrate_pdf(l, p, 105), 1.0, 0.03);
    // Sampled points lie on the sphere.
    for (uint32_t i = 0; i < 1000; ++i) {
        LightSample s = l.sample_li(p, uniform2(106, i));
        ASSERT_TRUE(s.valid());
        EXPECT_NEAR(length(s.p_light - Vec3(1, 2, 3)), 0.8f, 1e-3f);
    }
    // Chi-square: directions in the frame of the axis, cells aligned with the cone.
    Frame f(Vec3(1, 2, 3) / dist);
    const int nc = 12, np = 12;
    const uint32_t n = 200000;
    std::vector<double> obs(nc * np, 0), exp(nc * np, double(n) / (nc * np));
    for (uint32_t i = 0; i < n; ++i) {
        LightSample s = l.sample_li(p, uniform2(107, i));
        Vec3 w = f.to_local(s.wi);
        double u = (1 - double(w.z)) / (1 - cos_max);
        ASSERT_LE(u, 1.0 + 1e-3);
        double phi = std::atan2(double(w.y), double(w.x));
        if (phi < 0) phi += 2 * M_PI;
        int a = std::min(nc - 1, std::max(0, int(u * nc))), b = std::min(np - 1, int(phi / (2 * M_PI) * np));
        obs[a * np + b] += 1;
    }
    Chi2Result r = chi2_test(obs, exp);
    EXPECT_TRUE(r.passed(k_alpha)) << r.message << "\n" << dump_table(obs, exp, np);
    // From inside the sphere: dark, no NaN.
    EXPECT_FALSE(l.sample_li(Vec3(1, 2, 3.1f), Vec2(0.5f, 0.5f)).valid());
}

TEST(Lights, TriangleSolidAngleAndPdf) {
    Vec3 a(-1, -1, 1), b(2, -1, 1.5f), c(0, 2, 1);
    TriangleLight l(a, b, c, Spectrum(1.f), 0, 0);
    Vec3 p(0.f);
    // Van Oosterom & Strackee.
    Vec3 r1 = a - p, r2 = b - p, r3 = c - p;
    double l1 = length(r1), l2 = length(r2), l3 = length(r3);
    double num = std::fabs(dot(r1, cross(r2, r3)));
    double den = l1 * l2 * l3 + dot(r1, r2) * l3 + dot(r1, r3) * l2 + dot(r2, r3) * l1;
    double omega = 2 * std::atan2(num, den);
    expect_solid_angle(l, p, 108, omega);
    EXPECT_NEAR(integrate_pdf(l, p, 109), 1.0, 0.03);
    // Two-sided.
    EXPECT_TRUE(l.sample_li(Vec3(0, 0, 5), Vec2(0.3f, 0.3f)).valid());
}

TEST(Lights, DistantConeAndDelta) {
    LightDesc d = desc(LightDesc::Kind::distant, Mat4::rotate(30, 1, 0, 0));
    d.angle = 10.f;
    DistantLight cone(d);
    Vec3 axis = normalize(Mat4::rotate(30, 1, 0, 0).transform_vector(Vec3(0, 0, 1)));
    double omega = 2 * M_PI * (1 - std::cos(5 * M_PI / 180));
    expect_solid_angle(cone, Vec3(0.f), 110, omega);
    EXPECT_NEAR(integrate_pdf(cone, Vec3(0.f), 111, 2000000), 1.0, 0.05);
    EXPECT_EQ(cone.le_escape(axis), d.radiance);
    EXPECT_EQ(cone.le_escape(-axis), Spectrum(0.f));
    d.angle = 0.f;
    DistantLight delta(d);
    EXPECT_TRUE(delta.is_delta());
    LightSample s = delta.sample_li(Vec3(0.f), Vec2(0.1f, 0.9f));
    EXPECT_TRUE(s.is_delta);
    EXPECT_NEAR(length(s.wi - axis), 0.f, 1e-6f);
    EXPECT_EQ(delta.pdf_li(Vec3(0.f), axis), 0.f);
}

TEST(Lights, DomeIsUniform) {
    DomeLight dome(desc(LightDesc::Kind::dome, Mat4()));
    EXPECT_NEAR(integrate_pdf(dome, Vec3(0.f), 112, 10000), 1.0, 1e-6);
    EXPECT_EQ(dome.le_escape(Vec3(0, 1, 0)), Spectrum(2.f, 3.f, 4.f));
}

TEST(Lights, DegenerateLightsGiveNoSamplesAndNoNaN) {
    LightDesc r = desc(LightDesc::Kind::rect, Mat4());
    r.width = 0.f;
    LightDesc k = desc(LightDesc::Kind::disk, Mat4());
    k.radius = 0.f;
    LightDesc s = desc(LightDesc::Kind::sphere, Mat4());
    s.radius = 0.f;
    LightDesc pt = s;
    pt.treat_as_point = true;
    RectLight rl(r);
    DiskLight dl(k);
    SphereLight sl(s), pl(pt);
    TriangleLight tl(Vec3(0, 0, 1), Vec3(1, 0, 1), Vec3(2, 0, 1), Spectrum(1.f), 0, 0);
    for (const Light* l : std::vector<const Light*>{&rl, &dl, &sl, &pl, &tl}) {
        for (uint32_t i = 0; i < 100; ++i) {
            LightSample ls = l->sample_li(Vec3(0.3f, 0.2f, -1.f), uniform2(113, i));
            EXPECT_FALSE(ls.valid());
            EXPECT_TRUE(std::isfinite(l->pdf_li(Vec3(0.f, 0.f, -1.f), Vec3(0, 0, 1))));
        }
        EXPECT_TRUE(std::isfinite(l->power()));
    }
    // A point light at the reference point itself: no sample, no NaN.
    LightDesc p2 = pt;
    p2.radius = 1.f;
    SphereLight at(p2);
    EXPECT_FALSE(at.sample_li(Vec3(0.f), Vec2(0.5f, 0.5f)).valid());
}

TEST(Lights, IrradianceOnAxisByLightAndByCosineSampling) {
    // Disk of radius R at height h facing down: E = pi L R^2 / (h^2 + R^2) at the origin.
    LightDesc d = desc(LightDesc::Kind::disk, Mat4::translate(0, 1, 0) * Mat4::rotate(-90, 1, 0, 0));
    d.radius = 0.5f;
    d.radiance = Spectrum(1.f);
    DiskLight l(d);
    const int n = 400000;
    double e_light = 0, e_bsdf = 0;
    Frame f(Vec3(0, 1, 0));
    for (int i = 0; i < n; ++i) {
        LightSample s = l.sample_li(Vec3(0.f), uniform2(120, uint32_t(i)));
        if (s.valid()) e_light += s.li.x * std::max(0.f, s.wi.y) / s.pdf;
        Vec3 w = f.to_world(square_to_cosine_hemisphere(uniform2(121, uint32_t(i))));
        float t;
        Spectrum le;
        if (l.intersect(Ray(Vec3(0.f), w), &t, &le)) e_bsdf += le.x * k_pi;
    }
    double expected = M_PI * 0.25 / 1.25;
    EXPECT_NEAR(e_light / n, expected, 0.01 * expected);
    EXPECT_NEAR(e_bsdf / n, expected, 0.01 * expected);
}
