// Light sampling, what the light transport relies on:
//  1. chi-square of sample_li against pdf_li for the rect, disk, triangle (emissive mesh)
//     and cylinder lights: directions seen from a reference point, histogrammed over the
//     sphere in a frame pointing at the light, expected counts from pdf_li integrated per
//     cell (the direction harness, tests/cpp/support/direction_chi2.h: fine table, coarse table,
//     and the total mass -- the fraction of valid samples must equal the integral of
//     pdf_li, so pdf_li and sample_li must agree on which directions see the light);
//  2. emission sampling for every area light type (rect, disk, sphere, triangle,
//     cylinder): pdf_le at each sampled (p, d) equals the densities sample_le reported;
//     pdf_pos is 1 / (the area computed here independently); directions are
//     chi-square-tested against pdf_le's direction density in the frame of the emitting
//     normal; positions are chi-square-tested against the uniform area density in the
//     light's own parametrisation; and the flux the emission samples estimate equals
//     power();
//  3. light selection: Scene::build_lights' pmf is proportional to the powers of a rect,
//     disk, sphere, cylinder, black light (the floor), dome, distant lights and an emissive
//     triangle, computed here independently, and sample_light draws by it.
//
// False alarms: 19 chi-square tests in this file at alpha = 1e-3 / 19 each (Bonferroni:
// 1e-3 for the file); the other checks are exact up to float rounding.
#include "chi2.h"
#include "direction_chi2.h"
#include "test_util.h"

#include "lights/area_lights.h"
#include "lights/cylinder_light.h"
#include "lights/sphere_light.h"
#include "lights/triangle_light.h"
#include "math/frame.h"
#include "scene/interaction.h"
#include "sampling/warp.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <vector>

using namespace cmlt;
using namespace cmlt::test;

namespace {

constexpr int k_num_chi2 = 19;
constexpr double k_alpha = 1e-3 / k_num_chi2;

/// A grey material and one quad far from everything: the scene the tests below add their
/// lights to.
void add_far_quad(Scene& s) {
    s.set_materials({Material{Spectrum(0.5f), Spectrum(0.f)}});
    s.add_instance(s.add_mesh("/far", quad_mesh(Vec3(1e4f), Vec3(1, 0, 0), Vec3(0, 0, -1), 0)), Mat4());
}

/// Where the culling tests below place their lights: near the origin, hundreds of units
/// from it (rotated, non-uniformly scaled) and a thousandth of the size.
const Mat4 k_light_places[] = {Mat4::translate(0.3, -0.2, 1.2) * Mat4::rotate(25, 1, 0.5, 0),
                               Mat4::translate(400, 70, -300) * Mat4::rotate(70, 0.2, 1, 0.3) * Mat4::scale(3, 0.2, 1),
                               Mat4::translate(-1e-3, 2e-3, 1e-3) * Mat4::scale(1e-3, 1e-3, 1e-3)};
const LightDesc::Kind k_area_kinds[] = {LightDesc::Kind::rect, LightDesc::Kind::disk, LightDesc::Kind::sphere,
                                        LightDesc::Kind::cylinder};

/// A light of `kind` at xf with the culling tests' sizes (1.5 x 0.8 rect, radius 0.6,
/// length 2).
LightDesc sized_light(LightDesc::Kind kind, const Mat4& xf);

/// Ray i of streams s .. s + 5: from 1.5 to 300 radii r away from c, aimed at a point
/// 0.9 to 1.1 radii from it (a light's bounding sphere's rim, where culling decides), its
/// direction of length 0.01 to 100, its segment (tfar) unbounded for a quarter of the
/// rays and otherwise ending before, at or beyond the aimed point.
Ray rim_ray(const Vec3& c, float r, uint32_t s, uint32_t i) {
    const Vec3 o = c + square_to_uniform_sphere(uniform2(s, i)) * (r * std::pow(10.f, 0.18f + 2.3f * uniform2(s + 1, i).x));
    const Vec3 aim = c + square_to_uniform_sphere(uniform2(s + 2, i)) * (r * (0.9f + 0.2f * uniform2(s + 3, i).x));
    const float scale = std::pow(10.f, -2.f + 4.f * uniform2(s + 4, i).y);
    const float dist = length(aim - o);
    const float u = uniform2(s + 5, i).y;
    return Ray(o, (aim - o) * (scale / dist), 0.f, u < 0.25f ? k_infinity : dist / scale * (0.5f + 1.5f * u));
}

LightDesc desc(LightDesc::Kind kind, const Mat4& xf) {
    LightDesc d;
    d.kind = kind;
    d.transform = xf;
    d.radiance = Spectrum(2.f, 3.f, 4.f);
    return d;
}

LightDesc sized_light(LightDesc::Kind kind, const Mat4& xf) {
    LightDesc d = desc(kind, xf);
    d.width = 1.5f;
    d.height = 0.8f;
    d.radius = 0.6f;
    d.length = 2.f;
    return d;
}

/// Chi-square of l.sample_li(p, .) against l.pdf_li(p, .), in a frame whose +z points
/// from p to `toward` (so that the light covers many theta cells).
void expect_li_chi2(const Light& l, const Vec3& p, const Vec3& toward, const std::string& name,
                    uint32_t stream, int n = 400000) {
    Frame f(normalize(toward - p));
    Chi2Options opt;
    opt.theta_res = 48;
    opt.phi_res = 96;
    opt.coarse_factor = 8;
    opt.sample_count = n;
    opt.significance = k_alpha;
    opt.stream_id = stream;
    opt.name = "light_li_" + name;
    opt.integration_eps = 1e-7;  // per cell: 0.04 expected samples at n = 400k
    SphericalChi2Test test(
        [&](float, const Vec2& u) -> std::optional<Vec3> {
            LightSample s = l.sample_li(p, u);
            if (!s.valid()) return std::nullopt;
            return f.to_local(s.wi);
        },
        [&](const Vec3& w) { return double(l.pdf_li(p, f.to_world(w))); }, opt);
    Chi2Outcome r = test.run();
    EXPECT_TRUE(r.passed) << name << ": " << r.message << " (tables: " << r.dump_path << ")";
    EXPECT_GT(r.valid_fraction, 0.2) << name << ": too few valid samples to mean anything";
    std::printf("[%s] %s\n", name.c_str(), r.message.c_str());
}

// ---- emission --------------------------------------------------------------------------

/// What the emission test needs to know about a light, written independently of it.
struct EmitterCase {
    std::string name;
    const Light* light;
    double area;                 ///< emitting area (analytic)
    bool two_sided;
    Spectrum radiance;           ///< constant emitted radiance
    /// Position -> cell in [0, cells) of equal area (the light's own parametrisation).
    std::function<int(const Vec3&)> cell;
    int cells;
    /// Cells that are only half inside (triangle grid diagonal): expected mass 1/2.
    std::function<double(int)> cell_weight = [](int) { return 1.0; };
};

void expect_emission(const EmitterCase& c, uint32_t stream, int n = 200000) {
    const Light& l = *c.light;
    // (a) per-sample consistency, positions histogram, flux.
    std::vector<double> obs(size_t(c.cells), 0.0), exp(size_t(c.cells), 0.0);
    double wsum = 0;
    for (int k = 0; k < c.cells; ++k) wsum += c.cell_weight(k);
    for (int k = 0; k < c.cells; ++k) exp[size_t(k)] = n * c.cell_weight(k) / wsum;
    double flux = 0;
    int bad = 0;
    for (int i = 0; i < n; ++i) {
        LightLeSample s = l.sample_le(uniform2(stream, uint32_t(i)), uniform2(stream + 1, uint32_t(i)));
        if (!s.valid()) {
            ++bad;
            continue;
        }
        float pp, pd;
        l.pdf_le(s.p, s.d, &pp, &pd);
        if (i < 20000) {
            ASSERT_NEAR(length(s.d), 1.f, 1e-5f);
            ASSERT_NEAR(length(s.n), 1.f, 1e-5f);
            ASSERT_GT(dot(s.n, s.d), 0.f) << c.name << ": emitted away from the emitting side";
            ASSERT_NEAR(pp, s.pdf_pos, 1e-5f * pp) << c.name;
            ASSERT_NEAR(pd, s.pdf_dir, 2e-3f * pd + 1e-6f) << c.name << " sample " << i;
            ASSERT_NEAR(s.pdf_pos, 1.0 / c.area, 1e-4 / c.area) << c.name << ": pdf_pos is not 1/area";
            Vec3 ne = l.emitter_normal(s.p);
            ASSERT_NEAR(std::fabs(dot(ne, s.n)), 1.f, 1e-4f) << c.name;
            if (!c.two_sided) {
                ASSERT_GT(dot(ne, s.n), 0.f) << c.name;
            }
            ASSERT_EQ(s.le, c.radiance) << c.name;
        }
        obs[size_t(c.cell(s.p))] += 1;
        flux += luminance(s.le) * std::fabs(dot(s.n, s.d)) / (double(s.pdf_pos) * s.pdf_dir);
    }
    EXPECT_EQ(bad, 0) << c.name << ": invalid emission samples";
    Chi2Result r = chi2_test(obs, exp);
    EXPECT_TRUE(r.passed(k_alpha)) << c.name << " positions: " << r.message << "\n"
                                   << dump_table(obs, exp, 16);
    // Flux = integral of L cos over area and hemisphere(s) = pi A L (2 pi A L two-sided),
    // which is what power() must return for an unshaped light.
    double expect_flux = (c.two_sided ? 2 : 1) * M_PI * c.area * luminance(c.radiance);
    EXPECT_NEAR(flux / n, expect_flux, 1e-3 * expect_flux) << c.name << ": flux by emission sampling";
    EXPECT_NEAR(l.power(), expect_flux, 1e-3 * expect_flux) << c.name << ": power()";

    // (b) directions: chi-square in the frame of the emitter normal at the sampled point
    // (the fixed normal for a two-sided triangle, whose back-side samples land in the
    // lower hemisphere), against pdf_le's direction density at a fixed point (the
    // density is the same function of the local direction everywhere on the light).
    LightLeSample ref = l.sample_le(Vec2(0.37f, 0.61f), Vec2(0.2f, 0.3f));
    ASSERT_TRUE(ref.valid());
    Frame fref(l.emitter_normal(ref.p));
    uint32_t counter = 0;
    Chi2Options opt;
    opt.theta_res = 48;
    opt.phi_res = 96;
    opt.sample_count = 400000;
    opt.significance = k_alpha;
    opt.stream_id = stream + 2;
    opt.name = "light_le_dir_" + c.name;
    SphericalChi2Test test(
        [&](float, const Vec2& u) -> std::optional<Vec3> {
            LightLeSample s = l.sample_le(uniform2(stream + 3, counter++), u);
            if (!s.valid()) return std::nullopt;
            return Frame(l.emitter_normal(s.p)).to_local(s.d);
        },
        [&](const Vec3& w) {
            float pp, pd;
            l.pdf_le(ref.p, fref.to_world(w), &pp, &pd);
            return double(pd);
        },
        opt);
    Chi2Outcome o = test.run();
    EXPECT_TRUE(o.passed) << c.name << " directions: " << o.message << " (tables: " << o.dump_path << ")";
    std::printf("[%s emission] positions %s; directions %s\n", c.name.c_str(), r.message.c_str(),
                o.message.c_str());
}

int grid_cell(double a, double b, int na, int nb) {
    int i = std::min(na - 1, std::max(0, int(a * na)));
    int j = std::min(nb - 1, std::max(0, int(b * nb)));
    return i * nb + j;
}

}  // namespace

// ---- sample_li against pdf_li ------------------------------------------------------------

TEST(LightSampling, RectLiChi2) {
    // Oblique 1.5 x 0.8 rect (emitting toward the origin) and a sheared, non-uniformly
    // scaled one: area, pdf and sampling must all see the same parallelogram.
    Mat4 xf = Mat4::translate(0.3, -0.2, 1.2) * Mat4::rotate(25, 1, 0.5, 0);
    LightDesc d = desc(LightDesc::Kind::rect, xf);
    d.width = 1.5f;
    d.height = 0.8f;
    RectLight l(d);
    expect_li_chi2(l, Vec3(0.f), xf.transform_point(Vec3(0.f)), "rect", 400);
    Mat4 shear;
    shear.m[0][1] = 0.4;
    LightDesc d2 = d;
    d2.transform = xf * shear * Mat4::scale(1.6, 0.5, 1.0);
    RectLight l2(d2);
    expect_li_chi2(l2, Vec3(0.1f, 0.f, -0.3f), d2.transform.transform_point(Vec3(0.f)), "rect_sheared", 401);
}

TEST(LightSampling, DiskLiChi2) {
    // A disk close to the point (a wide cone, grazing edges) and an elliptical one
    // (non-uniform scale).
    Mat4 xf = Mat4::translate(0.2, 0.1, 0.5) * Mat4::rotate(-30, 0, 1, 0);
    LightDesc d = desc(LightDesc::Kind::disk, xf);
    d.radius = 0.7f;
    DiskLight l(d);
    expect_li_chi2(l, Vec3(0.f), xf.transform_point(Vec3(0.f)), "disk", 402);
    LightDesc d2 = d;
    d2.transform = Mat4::translate(-0.3, 0.2, 1.5) * Mat4::rotate(20, 1, 0, 0) * Mat4::scale(1.5, 0.6, 1.0);
    DiskLight l2(d2);
    expect_li_chi2(l2, Vec3(0.f), d2.transform.transform_point(Vec3(0.f)), "disk_elliptic", 403);
}

TEST(LightSampling, TriangleLiChi2) {
    // An emissive mesh triangle, seen from both sides (it emits on both).
    Vec3 a(-1, -1, 1), b(2, -1, 1.5f), c(0, 2, 1);
    TriangleLight l(a, b, c, Spectrum(1.f, 2.f, 3.f), 0, 0);
    Vec3 centre = (a + b + c) / 3.f;
    expect_li_chi2(l, Vec3(0.f), centre, "triangle_front", 404);
    expect_li_chi2(l, Vec3(0.5f, 0.2f, 2.2f), centre, "triangle_back", 405);
}

TEST(LightSampling, CylinderLiChi2) {
    // Broadside (about half the side faces the point) and from near one end at an
    // oblique angle (the visible side is cut by the open end: directions through the
    // end see the dark inside and must have pdf 0).
    Mat4 xf = Mat4::translate(0.2, -0.1, 0.3) * Mat4::rotate(35, 0, 1, 1);
    LightDesc d = desc(LightDesc::Kind::cylinder, xf);
    d.radius = 0.3f;
    d.length = 1.2f;
    CylinderLight l(d);
    Vec3 c = xf.transform_point(Vec3(0.f));
    expect_li_chi2(l, Vec3(0.f, 1.5f, 0.f), c, "cylinder_broadside", 406);
    Vec3 end = xf.transform_point(Vec3(0.6f, 0.f, 0.f));
    Vec3 axis = normalize(xf.transform_vector(Vec3(1.f, 0.f, 0.f)));
    Vec3 radial = normalize(cross(axis, Vec3(0.3f, 1.f, 0.2f)));
    Vec3 p = end + axis * 0.3f + radial * 0.75f;
    expect_li_chi2(l, p, c, "cylinder_end", 407);
}

// ---- sample_le against pdf_le --------------------------------------------------------------

TEST(LightSampling, EmissionRect) {
    Mat4 xf = Mat4::translate(0.3, -0.2, 1.2) * Mat4::rotate(25, 1, 0.5, 0);
    LightDesc d = desc(LightDesc::Kind::rect, xf);
    d.width = 1.5f;
    d.height = 0.8f;
    RectLight l(d);
    Mat4 inv = xf.inverse();
    EmitterCase c{"rect", &l, 1.5 * 0.8, false, d.radiance,
                  [&](const Vec3& p) {
                      Vec3 q = inv.transform_point(p);
                      return grid_cell(q.x / 1.5 + 0.5, q.y / 0.8 + 0.5, 16, 8);
                  },
                  128};
    expect_emission(c, 500);
}

TEST(LightSampling, EmissionDisk) {
    Mat4 xf = Mat4::translate(-0.3, 0.2, 1.5) * Mat4::rotate(20, 1, 0, 0) * Mat4::scale(1.5, 0.6, 1.0);
    LightDesc d = desc(LightDesc::Kind::disk, xf);
    d.radius = 0.7f;
    DiskLight l(d);
    Mat4 inv = xf.inverse();
    // Equal-area cells: (r / R)^2 and the angle.
    EmitterCase c{"disk", &l, M_PI * 0.7 * 0.7 * 1.5 * 0.6, false, d.radiance,
                  [&](const Vec3& p) {
                      Vec3 q = inv.transform_point(p);
                      double r2 = (double(q.x) * q.x + double(q.y) * q.y) / (0.49);
                      double phi = std::atan2(double(q.y), double(q.x)) / (2 * M_PI) + 0.5;
                      return grid_cell(r2, phi, 8, 16);
                  },
                  128};
    expect_emission(c, 510);
}

TEST(LightSampling, EmissionSphere) {
    LightDesc d = desc(LightDesc::Kind::sphere, Mat4::translate(1, 2, 3));
    d.radius = 0.8f;
    SphereLight l(d);
    // Equal-area cells: z (Archimedes) and the angle about the centre.
    EmitterCase c{"sphere", &l, 4 * M_PI * 0.64, false, d.radiance,
                  [&](const Vec3& p) {
                      Vec3 q = (p - Vec3(1, 2, 3)) / 0.8f;
                      double phi = std::atan2(double(q.y), double(q.x)) / (2 * M_PI) + 0.5;
                      return grid_cell(0.5 * (double(q.z) + 1), phi, 8, 16);
                  },
                  128};
    expect_emission(c, 520);
}

TEST(LightSampling, EmissionTriangle) {
    Vec3 a(-1, -1, 1), b(2, -1, 1.5f), cc(0, 2, 1);
    TriangleLight l(a, b, cc, Spectrum(1.f, 2.f, 3.f), 0, 0);
    Vec3 e1 = b - a, e2 = cc - a;
    double area = 0.5 * length(cross(e1, e2));
    // Barycentric (b1, b2) grid over the unit square: the simplex b1 + b2 <= 1 holds the
    // cells with i + j < n - 1 whole and those with i + j = n - 1 exactly half.
    const int n = 12;
    auto bary = [=](const Vec3& p) {
        Vec3 w = p - a;
        double d00 = dot(e1, e1), d01 = dot(e1, e2), d11 = dot(e2, e2);
        double d20 = dot(w, e1), d21 = dot(w, e2), den = d00 * d11 - d01 * d01;
        return std::make_pair((d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den);
    };
    EmitterCase c{"triangle", &l, area, true, Spectrum(1.f, 2.f, 3.f),
                  [=](const Vec3& p) {
                      auto b12 = bary(p);
                      return grid_cell(b12.first, b12.second, n, n);
                  },
                  n * n,
                  [=](int k) {
                      int i = k / n, j = k % n;
                      return i + j < n - 1 ? 1.0 : (i + j == n - 1 ? 0.5 : 0.0);
                  }};
    expect_emission(c, 530);
}

TEST(LightSampling, EmissionCylinder) {
    Mat4 xf = Mat4::translate(0.2, -0.1, 0.3) * Mat4::rotate(35, 0, 1, 1);
    LightDesc d = desc(LightDesc::Kind::cylinder, xf);
    d.radius = 0.3f;
    d.length = 1.2f;
    CylinderLight l(d);
    Mat4 inv = xf.inverse();
    EmitterCase c{"cylinder", &l, 2 * M_PI * 0.3 * 1.2, false, d.radiance,
                  [&](const Vec3& p) {
                      Vec3 q = inv.transform_point(p);
                      double phi = std::atan2(double(q.z), double(q.y)) / (2 * M_PI) + 0.5;
                      return grid_cell(q.x / 1.2 + 0.5, phi, 8, 16);
                  },
                  128};
    expect_emission(c, 540);
}

// ---- light selection by power --------------------------------------------------------------

TEST(LightSelection, PmfProportionalToPower) {
    // Scene::build_lights: pmf_i = max(power_i, floor) / sum, floor = 1e-3 x the mean
    // power. Powers written out here independently (Rec.709 luminance Y of the radiance):
    // one-sided planar pi A Y, sphere pi (4 pi r^2) Y, cylinder pi (2 pi r l) Y, emissive
    // triangle (two-sided) 2 pi A Y, dome pi R^2 (4 pi) Y and distant pi R^2 E (R: the
    // scene's bounding radius; E = Y for a delta light, 2 pi (1 - cos(angle / 2)) Y
    // otherwise); a black light gets the floor.
    Scene s;
    s.set_materials({Material{Spectrum(0.5f), Spectrum(0.f)}, Material{Spectrum(0.f), Spectrum(3.f, 2.f, 1.f)}});
    s.add_instance(s.add_mesh("/floor", quad_mesh(Vec3(0.f), Vec3(2, 0, 0), Vec3(0, 0, -2), 0)), Mat4());
    // One emissive triangle (material 1): (0,1,0) (1,1,0) (0,1,-0.5), area 0.25.
    s.add_instance(s.add_mesh("/tri", make_mesh_data({Vec3(0, 1, 0), Vec3(1, 1, 0), Vec3(0, 1, -0.5f)},
                                                     {0, 1, 2}, {1})),
                   Mat4());
    auto Y = [](const Spectrum& c) { return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z; };
    std::vector<double> want;
    LightDesc rect = desc(LightDesc::Kind::rect, Mat4::translate(0, 2, 0) * Mat4::rotate(90, 1, 0, 0));
    rect.width = 0.5f;
    rect.height = 0.4f;
    s.add_light(rect);
    want.push_back(M_PI * 0.2 * Y(rect.radiance));
    LightDesc disk = desc(LightDesc::Kind::disk, Mat4::translate(1, 2, 0));
    disk.radius = 0.3f;
    disk.radiance = Spectrum(10.f, 5.f, 1.f);
    s.add_light(disk);
    want.push_back(M_PI * M_PI * 0.09 * Y(disk.radiance));
    LightDesc sph = desc(LightDesc::Kind::sphere, Mat4::translate(-1, 1, 0));
    sph.radius = 0.1f;
    sph.radiance = Spectrum(50.f);
    s.add_light(sph);
    want.push_back(M_PI * 4 * M_PI * 0.01 * 50.0);
    LightDesc cyl = desc(LightDesc::Kind::cylinder, Mat4::translate(0, 1.5, -1));
    cyl.radius = 0.05f;
    cyl.length = 1.5f;
    s.add_light(cyl);
    want.push_back(M_PI * 2 * M_PI * 0.05 * 1.5 * Y(cyl.radiance));
    LightDesc black = desc(LightDesc::Kind::sphere, Mat4::translate(1, 1, 1));
    black.radiance = Spectrum(0.f);
    s.add_light(black);
    want.push_back(0.0);  // floor
    LightDesc dome = desc(LightDesc::Kind::dome, Mat4());
    dome.radiance = Spectrum(0.2f, 0.3f, 0.4f);
    s.add_light(dome);
    LightDesc sun = desc(LightDesc::Kind::distant, Mat4::rotate(-50, 1, 0, 0));
    sun.angle = 2.f;
    sun.radiance = Spectrum(1000.f);
    s.add_light(sun);
    LightDesc dsun = desc(LightDesc::Kind::distant, Mat4::rotate(-30, 0, 0, 1));
    dsun.angle = 0.f;
    dsun.radiance = Spectrum(0.5f);
    s.add_light(dsun);
    s.set_camera(camera_at(Mat4::translate(0, 1, 3)));
    s.commit();
    const double R = s.bounds_radius();
    want.push_back(M_PI * R * R * 4 * M_PI * Y(dome.radiance));
    double half = 1.0 * M_PI / 180;  // angle / 2
    want.push_back(M_PI * R * R * 2 * M_PI * (1 - std::cos(half)) * 1000.0);
    want.push_back(M_PI * R * R * 0.5);
    want.push_back(2 * M_PI * 0.25 * Y(Spectrum(3.f, 2.f, 1.f)));  // the triangle, listed last
    ASSERT_EQ(s.light_count(), want.size());
    double total = 0;
    for (double w : want) total += w;
    const double floor = 1e-3 * total / double(want.size());
    double norm = 0;
    for (double& w : want) norm += (w = std::max(w, floor));
    for (size_t i = 0; i < want.size(); ++i) {
        EXPECT_NEAR(s.light(i).power(), i == 4 ? 0.0 : want[i], 2e-4 * want[i]) << "light " << i;
        EXPECT_NEAR(s.light_pmf(i), want[i] / norm, 2e-4 * want[i] / norm + 1e-9) << "light " << i;
    }
    // sample_light draws by that pmf (chi-square; one of the 19 tests of this file).
    const uint32_t n = 200000;
    std::vector<double> obs(want.size(), 0.0), exp(want.size(), 0.0);
    for (size_t i = 0; i < want.size(); ++i) exp[i] = n * double(s.light_pmf(i));
    for (uint32_t k = 0; k < n; ++k) {
        float pmf = 0.f;
        size_t li = s.sample_light(uniform2(600, k).x, &pmf);
        ASSERT_LT(li, want.size());
        ASSERT_EQ(pmf, s.light_pmf(li));
        obs[li] += 1;
    }
    Chi2Result r = chi2_test(obs, exp);
    EXPECT_TRUE(r.passed(k_alpha)) << r.message << "\n" << dump_table(obs, exp, 9);
}

TEST(LightSampling, NextEventShadowRaysAreNotBlockedByTheirOwnPlanarLight) {
    // Scene::blocked_by_light(ray, target) leaves out the rect or disk light whose sampled
    // point the shadow ray aims at (path_tracer_impl.h: SurfacePoint::spawn_ray_to(
    // shadow_target(..)), ending at 1 - k_shadow_epsilon of the way): that segment ends
    // short of the light's plane, so the light cannot block it. The light's float
    // intersect said otherwise where rounding eats the 1e-4 margin: rays grazing the
    // plane, and points a few centimetres from a light placed hundreds of units from the
    // origin (there 0.01 % of the distance is below the coordinates' resolution). Here:
    // lights placed, rotated, sheared and scaled, far from the origin too, sampled from
    // points all around them (a tenth of their size to 30 sizes away, half of them close
    // to the light's plane) on surfaces of every orientation, with a second rect light B
    // across the middle of each scene: every shadow ray is blocked exactly when B blocks
    // it. How often the target light's own intersect reported its ray is printed.
    std::vector<Mat4> xfs = {Mat4::translate(0.3, -0.2, 1.2) * Mat4::rotate(25, 1, 0.5, 0),
                             Mat4::translate(40, 7, -300) * Mat4::rotate(70, 0.2, 1, 0.3) * Mat4::scale(3, 0.2, 1),
                             Mat4::translate(-1e-3, 2e-3, 1e-3) * Mat4::scale(1e-3, 1e-3, 1e-3)};
    Mat4 shear;
    shear.m[0][1] = 0.4;
    xfs.push_back(Mat4::translate(0.0, 5.0, 0.0) * Mat4::rotate(-40, 0, 0, 1) * shear);
    size_t tested = 0, blocked_by_b = 0, own = 0;
    for (size_t which = 0; which < 2 * xfs.size(); ++which) {
        const Mat4& xf = xfs[which / 2];
        LightDesc d = desc(which % 2 ? LightDesc::Kind::disk : LightDesc::Kind::rect, xf);
        d.width = 1.5f;
        d.height = 0.8f;
        d.radius = 0.6f;
        const Vec3 c = xf.transform_point(Vec3(0.f));
        const float scale = length(xf.transform_vector(Vec3(1.f, 1.f, 0.f)));
        // B: a rect through the light's centre region, facing every way over the samples
        LightDesc b = desc(LightDesc::Kind::rect, Mat4::translate(c.x + scale, c.y, c.z) *
                                                      Mat4::rotate(-90, 0, 1, 0) * Mat4::scale(scale, scale, scale));
        b.width = 2.f;
        b.height = 2.f;
        Scene s;
        add_far_quad(s);
        const uint32_t target = s.add_light(d);
        const uint32_t other = s.add_light(b);
        s.commit();
        const Light& l = s.light(target);
        for (uint32_t i = 0; i < 20000; ++i) {
            Vec3 dir = square_to_uniform_sphere(uniform2(900, i));
            if (i % 2) {
                const Vec3 n = normalize(xf.transform_normal(Vec3(0.f, 0.f, -1.f)));
                dir = normalize(dir - n * (dot(dir, n) * (1.f - 1e-2f * uniform2(902, i).x)));
            }
            SurfacePoint sp;
            sp.p = c + dir * (scale * std::pow(10.f, -1.f + 2.5f * uniform2(903, i).x));
            sp.ng = square_to_uniform_sphere(uniform2(904, i));
            sp.error_scale = point_error_scale(sp.p);
            const LightSample ls = l.sample_li(sp.p, uniform2(906, i));
            if (!ls.valid()) continue;
            const Ray shadow = sp.spawn_ray_to(shadow_target(ls.p_light, ls.n_light, ls.error_scale, ls.wi));
            float t;
            Spectrum le;
            const bool by_b = s.light(other).intersect(shadow, &t, &le);
            ASSERT_EQ(s.blocked_by_light(shadow, target), by_b) << "light " << which << ", point " << i;
            float pass_pdf = 0.f;
            ASSERT_EQ(s.transmittance(shadow, target, &pass_pdf) == 0.f, by_b) << "light " << which << ", point " << i;
            EXPECT_EQ(pass_pdf, 1.f);
            own += l.intersect(shadow, &t, &le) ? 1 : 0;
            blocked_by_b += by_b ? 1 : 0;
            ++tested;
        }
    }
    EXPECT_GT(tested, 70000u);
    EXPECT_GT(blocked_by_b, 1000u);
    std::printf("shadow rays %zu, blocked by the other light %zu, reported by their own light's intersect %zu\n",
                tested, blocked_by_b, own);
}

TEST(LightSampling, TheBoundingSphereCullNeverLosesALightHit) {
    // Scene::nearest_light and blocked_by_light skip a light when the ray's segment stays
    // clear of a sphere around it (may_reach_light, a division-free float test). Here
    // every analytic area light kind, small and large, near the origin and hundreds of
    // units from it, against rays aimed at and just past the sphere's rim (unnormalised
    // directions, segments ending before, at and beyond the light): the culled query
    // finds exactly the hits of the lights' own intersects, tried one by one.
    size_t hits = 0, tested = 0;
    for (const Mat4& xf : k_light_places)
        for (LightDesc::Kind kind : k_area_kinds) {
            const LightDesc d = sized_light(kind, xf);
            Scene s;
            add_far_quad(s);
            const uint32_t id = s.add_light(d);
            s.commit();
            const Light& l = s.light(id);
            Vec3 c;
            float r = 0.f;
            ASSERT_TRUE(l.bounding_sphere(&c, &r));
            for (uint32_t i = 0; i < 40000; ++i) {
                Ray ray = rim_ray(c, r, 910, i);
                const float tmax = ray.tfar;
                ray.tfar = k_infinity;
                float t_ref = k_infinity, t = 0.f;
                Spectrum le;
                if (l.intersect(Ray(ray.o, ray.d, ray.tnear, tmax), &t, &le) && t < tmax) t_ref = t;
                uint32_t index = 0;
                const float t_scene = s.nearest_light(ray, tmax, &index, &le);
                ASSERT_EQ(t_scene, t_ref) << "light kind " << int(kind) << ", ray " << i;
                ray.tfar = tmax;
                ASSERT_EQ(s.blocked_by_light(ray), t_ref < k_infinity) << "light kind " << int(kind) << ", ray " << i;
                hits += t_ref < k_infinity;
                ++tested;
            }
        }
    EXPECT_GT(hits, tested / 10);
    std::printf("rays %zu, light hits %zu\n", tested, hits);
}

TEST(LightSampling, TheBvhsLightProxiesFindWhatTheLightsOwnTestsFind) {
    // With every analytic area light bounded, Scene::commit gives the BVH the lights as
    // proxies (Accel::set_light_proxies): one traversal finds the nearest of triangles
    // and lights, Embree calling the light's own intersect for rays that cross its box.
    // Every light kind, near the origin and hundreds of units from it, with a triangle
    // quad cutting through some of the rays (so the nearest of the two decides), rays
    // aimed at and just past the light's bounding sphere (unnormalised directions,
    // segments ending before, at and beyond the light), one by one and in packets of 4,
    // 8 and 16: the closest-hit queries find exactly the lights' own hits and Scene::
    // intersect says what it says with the lights out of the BVH (the scalar test after
    // the query); the occlusion queries are blocked exactly by a light hit or the
    // mesh, and not by a skipped proxy.
    size_t light_hits = 0, mesh_nearer = 0, tested = 0;
    for (const Mat4& xf : k_light_places)
        for (LightDesc::Kind kind : k_area_kinds) {
            const LightDesc d = sized_light(kind, xf);
            Scene with, without;
            without.set_light_proxies_enabled(false);
            Vec3 c;
            float r = 0.f;
            for (Scene* s : {&with, &without}) {
                add_far_quad(*s);
                s->add_light(d);
                s->commit();
                ASSERT_TRUE(s->light(0).bounding_sphere(&c, &r));
                // a quad through the light's centre, facing +x: in front of the light for
                // some rays, behind it for others
                s->add_instance(s->add_mesh("/cut", quad_mesh(c, Vec3(0, 0, 1) * (3 * r), Vec3(0, 1, 0) * (3 * r), 0)),
                                Mat4());
                s->commit();
            }
            ASSERT_TRUE(with.light_proxies());
            ASSERT_FALSE(without.light_proxies());
            const Light& l = with.light(0);
            const Accel& accel = with.accel();
            constexpr uint32_t n = 4096;
            std::vector<Ray> rays(n);
            std::vector<float> t_light(n);
            for (uint32_t i = 0; i < n; ++i) {
                rays[i] = rim_ray(c, r, 920, i);
                float t;
                Spectrum le;
                t_light[i] = l.intersect(rays[i], &t, &le) ? t : k_infinity;
            }
            std::vector<uint32_t> lanes(n);
            for (uint32_t i = 0; i < n; ++i) lanes[i] = i;
            for (int width : {1, 4, 8, 16}) {
                std::vector<Hit> hits(n);
                std::vector<uint8_t> occ(n), occ_skip(n), occ_mesh(n);
                const std::vector<uint32_t> skip(n, 0u);
                accel.intersect_lanes(rays.data(), lanes.data(), n, hits.data(), width, 4, true);
                accel.occluded_lanes(rays.data(), lanes.data(), n, occ.data(), width, 4, true);
                accel.occluded_lanes(rays.data(), lanes.data(), n, occ_skip.data(), width, 4, true, skip.data());
                accel.occluded_lanes(rays.data(), lanes.data(), n, occ_mesh.data(), width, 4);
                for (uint32_t i = 0; i < n; ++i) {
                    const Hit mesh = accel.intersect(rays[i]);
                    const bool light_first = t_light[i] < k_infinity && !(mesh.valid() && mesh.t <= t_light[i]);
                    ASSERT_EQ(hits[i].light_hit(), light_first) << "kind " << int(kind) << ", width " << width << ", ray " << i;
                    if (light_first) {
                        ASSERT_EQ(hits[i].t, t_light[i]) << "ray " << i;
                        ASSERT_EQ(hits[i].light, 0u);
                    } else {
                        ASSERT_EQ(hits[i].light, k_no_light_hit);
                        ASSERT_EQ(hits[i].valid(), mesh.valid()) << "ray " << i;
                    }
                    ASSERT_EQ(occ[i] != 0, t_light[i] < k_infinity || occ_mesh[i] != 0) << "ray " << i;
                    ASSERT_EQ(occ_skip[i], occ_mesh[i]) << "ray " << i;
                    if (width != 1) continue;
                    const SceneHit a = with.intersect(rays[i]), b = without.intersect(rays[i]);
                    ASSERT_EQ(int(a.kind), int(b.kind)) << "ray " << i;
                    ASSERT_EQ(a.t, b.t) << "ray " << i;
                    if (a.kind == SceneHit::Kind::light) {
                        ASSERT_EQ(a.le.x, b.le.x);
                        ASSERT_EQ(a.le.z, b.le.z);
                    }
                    light_hits += light_first;
                    mesh_nearer += !light_first && t_light[i] < k_infinity;
                    ++tested;
                }
            }
        }
    EXPECT_GT(light_hits, tested / 20);
    EXPECT_GT(mesh_nearer, tested / 50);
    std::printf("rays %zu, light hits %zu, mesh nearer than a light hit %zu\n", tested, light_hits, mesh_nearer);
}
