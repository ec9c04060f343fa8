/// \file Chi^2 tests of PreviewSurfaceBsdf::sample against PreviewSurfaceBsdf::pdf for every
/// non-delta lobe configuration and several outgoing directions (including grazing ones and
/// directions inside a dielectric). Family-wise level 0.01, Bonferroni-corrected over cases.
#include "bsdf_test_util.h"
#include "direction_chi2.h"

#include <gtest/gtest.h>

#include <cstdint>

namespace cmlt::test {
namespace {

struct Chi2Case {
    std::string name;
    PreviewSurfaceParams params;
    float theta_o_deg;
    float side;  ///< +1: wo outside / above, -1: inside / below
    /// Mixed Dirac + smooth configurations: Dirac samples are dropped (counted as missing
    /// mass), so the total-mass sub-test checks P(delta) = 1 - integral of pdf.
    bool has_delta = false;
};
std::ostream& operator<<(std::ostream& os, const Chi2Case& c) { return os << c.name; }

std::vector<Chi2Case> chi2_cases() {
    const Spectrum copper(0.95f, 0.64f, 0.54f);
    std::vector<Chi2Case> cases = {
        {"lambert_normal", lambert(Spectrum(0.8f)), 0.f, 1.f},
        {"lambert_70", lambert(Spectrum(0.8f)), 70.f, 1.f},
        {"metal_r0_2_at15", metal(copper, 0.2f), 15.f, 1.f},
        {"metal_r0_2_at60", metal(copper, 0.2f), 60.f, 1.f},
        {"metal_r0_2_at85", metal(copper, 0.2f), 85.f, 1.f},
        {"metal_r0_5_at30", metal(copper, 0.5f), 30.f, 1.f},
        {"metal_r0_5_at80", metal(copper, 0.5f), 80.f, 1.f},
        {"metal_r0_5_backside_at40", metal(copper, 0.5f), 40.f, -1.f},
        {"metal_r1_0_normal", metal(copper, 1.f), 0.f, 1.f},
        {"metal_r1_0_at45", metal(copper, 1.f), 45.f, 1.f},
        {"metal_r1_0_grazing_89_5", metal(copper, 1.f), 89.5f, 1.f},
        {"plastic_r0_4_at30", plastic(Spectrum(0.5f), 0.4f), 30.f, 1.f},
        {"plastic_r0_4_at75", plastic(Spectrum(0.5f), 0.4f), 75.f, 1.f},
        {"specular_workflow_at20",
         specular_workflow(Spectrum(0.6f, 0.3f, 0.1f), Spectrum(0.2f), 0.35f), 20.f, 1.f},
        {"specular_workflow_at70",
         specular_workflow(Spectrum(0.6f, 0.3f, 0.1f), Spectrum(0.2f), 0.35f), 70.f, 1.f},
        {"clearcoat_mix_at10", with_clearcoat(plastic(Spectrum(0.7f, 0.4f, 0.3f), 0.6f), 1.f, 0.2f),
         10.f, 1.f},
        {"clearcoat_mix_at65", with_clearcoat(plastic(Spectrum(0.7f, 0.4f, 0.3f), 0.6f), 1.f, 0.2f),
         65.f, 1.f},
        {"rough_glass_outside_at20", glass(0.3f, 1.5f), 20.f, 1.f},
        {"rough_glass_outside_at75", glass(0.3f, 1.5f), 75.f, 1.f},
        {"rough_glass_inside_at20", glass(0.3f, 1.5f), 20.f, -1.f},
        {"rough_glass_inside_at55_tir", glass(0.3f, 1.5f), 55.f, -1.f},
        {"rough_glass_r0_7_grazing_88", glass(0.7f, 1.33f), 88.f, 1.f},
        {"rough_bubble_ior0_75_at30", glass(0.4f, 0.75f), 30.f, 1.f},
        {"translucent_mix_outside_at40",
         with_opacity(with_clearcoat(plastic(Spectrum(0.5f), 0.5f), 0.5f, 0.3f), 0.5f), 40.f, 1.f},
        {"translucent_mix_inside_at40",
         with_opacity(with_clearcoat(plastic(Spectrum(0.5f), 0.5f), 0.5f, 0.3f), 0.5f), 40.f, -1.f},
        {"mixed_smooth_plastic_at50", plastic(Spectrum(0.5f), 0.f), 50.f, 1.f, true},
        {"mixed_smooth_clearcoat_over_rough_at30",
         with_clearcoat(plastic(Spectrum(0.6f), 0.5f), 1.f, 0.f), 30.f, 1.f, true},
        {"mixed_half_opaque_smooth_glass_at60", with_opacity(plastic(Spectrum(0.5f), 0.f), 0.5f),
         60.f, 1.f, true},
        {"mixed_half_opaque_smooth_glass_inside_at30",
         with_opacity(plastic(Spectrum(0.5f), 0.f), 0.5f), 30.f, -1.f, true},
    };
    return cases;
}

/// Portable string hash (stream ids must not depend on the standard library).
uint32_t fnv1a(const std::string& s) {
    uint32_t h = 2166136261u;
    for (unsigned char ch : s) h = (h ^ ch) * 16777619u;
    return h;
}

class PreviewSurfaceChi2 : public ::testing::TestWithParam<Chi2Case> {};

TEST_P(PreviewSurfaceChi2, sample_matches_pdf) {
    const Chi2Case& c = GetParam();
    const PreviewSurfaceBsdf bsdf(c.params);
    ASSERT_EQ(bsdf.has_delta(), c.has_delta);
    ASSERT_FALSE(bsdf.is_pure_delta());
    const Vec3 wo = direction_deg(c.theta_o_deg, 0.7f, c.side);

    static const int num_cases = int(chi2_cases().size());
    Chi2Options opt;
    opt.name = c.name;
    opt.significance = bonferroni(0.01, num_cases);
    opt.sample_count = 1000000;
    opt.seed = 0xC417u;
    opt.stream_id = fnv1a(c.name);

    long delta_samples = 0;
    SphericalChi2Test test(
        [&](float u1, const Vec2& u2) -> std::optional<Vec3> {
            std::optional<PreviewSurfaceSample> s = bsdf.sample(wo, u1, u2, TransportMode::Radiance);
            if (!s) return std::nullopt;
            if (s->is_delta) {
                ++delta_samples;
                return std::nullopt;
            }
            return s->wi;
        },
        [&](const Vec3& wi) { return double(bsdf.pdf(wo, wi)); }, opt);
    Chi2Outcome r = test.run();
    if (!c.has_delta) {
        EXPECT_EQ(delta_samples, 0);
    } else {
        EXPECT_GT(delta_samples, 0);
    }
    EXPECT_TRUE(r.passed) << c.name << ": " << r.message << "\n  tables: " << r.dump_path;
    EXPECT_LE(r.pdf_integral, 1.0 + 1e-3) << c.name;
    EXPECT_GT(r.valid_fraction, c.has_delta ? 0.1 : 0.3) << c.name;  // sanity: sampler mostly works
}

INSTANTIATE_TEST_SUITE_P(Cases, PreviewSurfaceChi2, ::testing::ValuesIn(chi2_cases()),
                         [](const ::testing::TestParamInfo<Chi2Case>& info) {
                             return info.param.name;
                         });

}  // namespace
}  // namespace cmlt::test
