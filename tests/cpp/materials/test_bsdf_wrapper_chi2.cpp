/// \file Chi^2 tests of the Lambertian BSDF (materials/lambertian.h, local frame) and of the
/// world-space `Bsdf` wrapper (materials/bsdf.h) around the Lambertian and UsdPreviewSurface
/// models with shading normals that differ from the geometric normal. The wrapper keeps only
/// pairs (wo, wi) whose shading-frame side classification agrees with the geometric one; its
/// `sample` and `pdf` must agree on that: directions are histogrammed over the sphere in
/// world space and compared with the integral of `Bsdf::pdf`, and the total-mass sub-test
/// checks that the fraction of samples that survive equals the integral of the pdf. Per
/// sample also: pdf and f of `sample` equal `pdf` and `eval` at the sampled direction, and
/// the sampled pair lies on consistent sides.
///
/// Family-wise level 0.01, Bonferroni-corrected over the cases of this file.
#include "bsdf_test_util.h"
#include "direction_chi2.h"

#include "materials/bsdf.h"
#include "math/frame.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>

namespace cmlt::test {
namespace {

/// A direction at polar angle theta (degrees) and azimuth phi about `n`.
Vec3 around(const Vec3& n, float theta_deg, float phi) {
    Frame f(n);
    float t = radians(theta_deg);
    return normalize(f.to_world(Vec3(std::sin(t) * std::cos(phi), std::sin(t) * std::sin(phi), std::cos(t))));
}

/// Shading normal tilted by `deg` from +z toward +x.
Vec3 tilted(float deg) {
    float t = radians(deg);
    return Vec3(std::sin(t), 0.f, std::cos(t));
}

struct WrapperCase {
    std::string name;
    bool lambert_model;              ///< Lambertian model, else PreviewSurface `params`
    PreviewSurfaceParams params;
    Vec3 ns, ng, wo;                 ///< world space
    double min_valid = 0.05;         ///< sanity: this fraction of samples at least survives
};
std::ostream& operator<<(std::ostream& os, const WrapperCase& c) { return os << c.name; }

const Vec3 k_ng(0.f, 0.f, 1.f);

std::vector<WrapperCase> wrapper_cases() {
    const Spectrum albedo(0.8f, 0.5f, 0.3f);
    const Vec3 ns30 = tilted(30.f), ns60 = tilted(60.f);
    std::vector<WrapperCase> cases = {
        // Shading normal = geometric normal: the plain lobe.
        {"lambert_flat_at40", true, {}, k_ng, k_ng, around(k_ng, 40.f, 0.3f)},
        // Tilted by 30 degrees (the shading hemisphere cuts through the geometric plane:
        // reflected samples below it are rejected): wo near ng; wo on the side the shading
        // normal leans away from; wo grazing the geometric plane on the side it leans
        // toward; wo below the geometric plane (back side).
        {"lambert_tilt30_wo_ng", true, {}, ns30, k_ng, around(k_ng, 5.f, 1.f)},
        {"lambert_tilt30_wo_away_40", true, {}, ns30, k_ng, around(k_ng, 40.f, 3.14159f)},
        {"lambert_tilt30_wo_toward_80", true, {}, ns30, k_ng, around(k_ng, 80.f, 0.f)},
        {"lambert_tilt30_back_at50", true, {}, ns30, k_ng, around(-k_ng, 50.f, 2.f)},
        // wo above the geometric plane but below the shading plane: the model reflects
        // into the -ns hemisphere, most of which is below the geometric plane (rejected).
        {"lambert_tilt30_wo_below_ns_70", true, {}, ns30, k_ng, around(k_ng, 70.f, 3.14159f), 0.01},
        {"lambert_tilt60_wo_below_ns_75", true, {}, ns60, k_ng, around(k_ng, 75.f, 3.14159f), 0.01},
        // UsdPreviewSurface models through the wrapper.
        {"metal_r0_5_tilt30_at50", false, metal(Spectrum(0.95f, 0.64f, 0.54f), 0.5f), ns30, k_ng,
         around(k_ng, 50.f, 3.14159f)},
        {"plastic_r0_3_tilt30_at20", false, plastic(Spectrum(0.5f), 0.3f), ns30, k_ng,
         around(k_ng, 20.f, 0.5f)},
        {"clearcoat_tilt30_at60", false, with_clearcoat(plastic(Spectrum(0.6f), 0.6f), 1.f, 0.2f),
         ns30, k_ng, around(k_ng, 60.f, 0.f)},
        // Rough glass: transmission pairs must be classified the same way by both frames.
        {"rough_glass_tilt30_outside_at35", false, glass(0.3f, 1.5f), ns30, k_ng,
         around(k_ng, 35.f, 2.5f)},
        {"rough_glass_tilt30_inside_at30", false, glass(0.3f, 1.5f), ns30, k_ng,
         around(-k_ng, 30.f, 1.f)},
        {"translucent_tilt30_at45", false, with_opacity(plastic(Spectrum(0.5f), 0.5f), 0.5f), ns30,
         k_ng, around(k_ng, 45.f, 0.2f)},
    };
    return cases;
}

uint32_t fnv1a(const std::string& s) {
    uint32_t h = 2166136261u;
    for (unsigned char ch : s) h = (h ^ ch) * 16777619u;
    return h;
}

int num_tests() { return int(wrapper_cases().size()) + 3; }  // + the Lambertian-model cases

// ---- the Lambertian model in its local frame -----------------------------------------------

class LambertianChi2 : public ::testing::TestWithParam<float> {};

TEST_P(LambertianChi2, sample_matches_pdf) {
    // theta_o in degrees; negative = wo below the surface (two-sided).
    const float th = GetParam();
    const LambertianBsdf bsdf(Spectrum(0.7f, 0.5f, 0.2f));
    const Vec3 wo = direction_deg(std::fabs(th), 0.4f, th < 0 ? -1.f : 1.f);
    Chi2Options opt;
    opt.name = "lambertian_" + std::to_string(int(th));
    opt.significance = bonferroni(0.01, num_tests());
    opt.sample_count = 500000;
    opt.integration_eps = 1e-7;
    opt.stream_id = fnv1a(opt.name);
    int checked = 0;
    SphericalChi2Test test(
        [&](float u1, const Vec2& u2) -> std::optional<Vec3> {
            BsdfSample s = bsdf.sample(wo, u2, u1);
            if (!s.valid()) return std::nullopt;
            if (checked < 5000) {
                ++checked;
                EXPECT_GT(s.wi.z * wo.z, 0.f);
                EXPECT_NEAR(s.pdf, bsdf.pdf(wo, s.wi), 1e-5f);
                EXPECT_EQ(s.f, bsdf.eval(wo, s.wi));
                // weight = albedo exactly (cosine sampling)
                Spectrum w = s.f * std::fabs(s.wi.z) / s.pdf;
                EXPECT_NEAR(w.x, 0.7f, 1e-4f);
            }
            return s.wi;
        },
        [&](const Vec3& wi) { return double(bsdf.pdf(wo, wi)); }, opt);
    Chi2Outcome r = test.run();
    EXPECT_TRUE(r.passed) << opt.name << ": " << r.message << "\n  tables: " << r.dump_path;
    EXPECT_NEAR(r.pdf_integral, 1.0, 1e-3);
    EXPECT_EQ(r.valid_fraction, 1.0);
}

INSTANTIATE_TEST_SUITE_P(Cases, LambertianChi2, ::testing::Values(0.f, 70.f, -40.f),
                         [](const ::testing::TestParamInfo<float>& info) {
                             float t = info.param;
                             return std::string(t < 0 ? "below_" : "above_") +
                                    std::to_string(int(std::fabs(t)));
                         });

// ---- the world-space wrapper with shading normals ------------------------------------------

class BsdfWrapperChi2 : public ::testing::TestWithParam<WrapperCase> {};

TEST_P(BsdfWrapperChi2, sample_matches_pdf) {
    const WrapperCase& c = GetParam();
    const Bsdf bsdf = c.lambert_model
                          ? Bsdf(LambertianBsdf(Spectrum(0.8f, 0.5f, 0.3f)), normalize(c.ns), c.ng)
                          : Bsdf(PreviewSurfaceBsdf(c.params), normalize(c.ns), c.ng);
    const Vec3 wo = c.wo;
    Chi2Options opt;
    opt.name = "bsdf_wrapper_" + c.name;
    opt.significance = bonferroni(0.01, num_tests());
    opt.sample_count = 500000;
    opt.integration_eps = 1e-7;  // per cell: 0.05 expected samples
    opt.seed = 0xB5DFu;
    opt.stream_id = fnv1a(c.name);
    long delta = 0, checked = 0, bad_pdf = 0, bad_f = 0, bad_side = 0;
    SphericalChi2Test test(
        [&](float u1, const Vec2& u2) -> std::optional<Vec3> {
            BsdfSample s = bsdf.sample(wo, u2, u1);
            if (!s.valid()) return std::nullopt;
            if (s.is_delta) {
                ++delta;
                return std::nullopt;
            }
            if (checked < 20000) {
                ++checked;
                float p = bsdf.pdf(wo, s.wi);
                if (!(std::fabs(p - s.pdf) <= 1e-3f * s.pdf + 1e-6f)) ++bad_pdf;
                Spectrum f = bsdf.eval(wo, s.wi);
                if (!(std::fabs(f.x - s.f.x) <= 1e-3f * s.f.x + 1e-6f)) ++bad_f;
                // Consistent sides: reflection iff both on the same side of ng.
                bool geo_reflect = dot(wo, c.ng) * dot(s.wi, c.ng) > 0.f;
                if (geo_reflect == s.is_transmission) ++bad_side;
            }
            return s.wi;
        },
        [&](const Vec3& wi) { return double(bsdf.pdf(wo, wi)); }, opt);
    Chi2Outcome r = test.run();
    EXPECT_EQ(delta, 0) << c.name;
    EXPECT_EQ(bad_pdf, 0) << c.name << ": sample's pdf != pdf() at the sampled direction";
    EXPECT_EQ(bad_f, 0) << c.name << ": sample's f != eval() at the sampled direction";
    EXPECT_EQ(bad_side, 0) << c.name << ": is_transmission disagrees with the geometric sides";
    EXPECT_TRUE(r.passed) << c.name << ": " << r.message << "\n  tables: " << r.dump_path;
    EXPECT_LE(r.pdf_integral, 1.0 + 1e-3) << c.name;
    EXPECT_GT(r.valid_fraction, c.min_valid) << c.name;
    std::printf("[%s] %s\n", c.name.c_str(), r.message.c_str());
}

INSTANTIATE_TEST_SUITE_P(Cases, BsdfWrapperChi2, ::testing::ValuesIn(wrapper_cases()),
                         [](const ::testing::TestParamInfo<WrapperCase>& info) {
                             return info.param.name;
                         });

}  // namespace
}  // namespace cmlt::test
