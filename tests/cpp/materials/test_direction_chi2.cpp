/// \file Self-tests of the chi^2 harness (chi2.h): the special function, the quadrature, and
/// that the test both accepts a correct sampler and rejects wrong ones (it has power).
#include "direction_chi2.h"

#include "sampling/warp.h"

#include <gtest/gtest.h>

#include <cmath>

namespace cmlt::test {
namespace {

TEST(Chi2Harness, test01_incomplete_gamma_known_values) {
    for (double x : {0.0, 0.1, 1.0, 2.5, 10.0, 40.0}) {
        EXPECT_NEAR(gamma_q(1.0, x), std::exp(-x), 1e-12) << x;
        EXPECT_NEAR(gamma_q(0.5, x), std::erfc(std::sqrt(x)), 1e-12) << x;
    }
    // Critical values of the chi^2 distribution at the 5 % level (standard tables).
    EXPECT_NEAR(chi2_sf(3.841459, 1), 0.05, 1e-6);
    EXPECT_NEAR(chi2_sf(18.307038, 10), 0.05, 1e-6);
    EXPECT_NEAR(chi2_sf(124.342113, 100), 0.05, 1e-6);
    EXPECT_NEAR(chi2_sf(1.0, 2), std::exp(-0.5), 1e-12);
    EXPECT_EQ(chi2_sf(0.0, 5), 1.0);
    EXPECT_LT(chi2_sf(1e4, 100), 1e-100);
}

TEST(Chi2Harness, test02_adaptive_simpson_resolves_a_narrow_peak) {
    // A Gaussian of width 1e-3 placed between the coarse Simpson nodes of [0, 1].
    const double s = 1e-3, m = 0.3;
    auto g = [&](double x) { return std::exp(-0.5 * (x - m) * (x - m) / (s * s)); };
    double exact = s * std::sqrt(2.0 * 3.14159265358979323846);
    EXPECT_NEAR(adaptive_simpson(g, 0.0, 1.0, 1e-12, 30, 4), exact, 1e-9);
    auto g2 = [&](double x, double y) { return g(x) * g(y); };
    EXPECT_NEAR(adaptive_simpson_2d(g2, 0.0, 1.0, 0.0, 1.0, 1e-12, 30, 4), exact * exact, 1e-10);
}

Chi2Options small_options(const char* name) {
    Chi2Options o;
    o.theta_res = 20;
    o.phi_res = 40;
    o.coarse_factor = 5;
    o.sample_count = 200000;
    o.significance = 0.01;
    o.integration_eps = 1e-8;
    o.name = name;
    return o;
}

TEST(Chi2Harness, test03_accepts_cosine_hemisphere_warp) {
    SphericalChi2Test t([](float, const Vec2& u) { return std::optional<Vec3>(square_to_cosine_hemisphere(u)); },
                        [](const Vec3& w) { return double(square_to_cosine_hemisphere_pdf(w)); },
                        small_options("self_cosine"));
    Chi2Outcome r = t.run();
    EXPECT_TRUE(r.passed) << r.message << " (tables: " << r.dump_path << ")";
    EXPECT_NEAR(r.pdf_integral, 1.0, 1e-6);
    EXPECT_EQ(r.valid_fraction, 1.0);
}

TEST(Chi2Harness, test04_rejects_wrong_pdf) {
    // Cosine-distributed samples tested against the uniform-hemisphere pdf.
    SphericalChi2Test t([](float, const Vec2& u) { return std::optional<Vec3>(square_to_cosine_hemisphere(u)); },
                        [](const Vec3& w) { return double(square_to_uniform_hemisphere_pdf(w)); },
                        small_options("self_wrong_pdf"));
    Chi2Outcome r = t.run();
    EXPECT_FALSE(r.passed) << r.message;
    EXPECT_LT(r.p_value, 1e-10);
}

TEST(Chi2Harness, test05_rejects_subtle_mismatch) {
    // Samples of cos^1 tested against a cos^1.05 lobe: a 5 % exponent error must be caught.
    auto pdf = [](const Vec3& w) {
        return w.z > 0.f ? (2.05 / (2.0 * 3.14159265358979323846)) * std::pow(double(w.z), 1.05) : 0.0;
    };
    Chi2Options o = small_options("self_subtle");
    o.sample_count = 1000000;
    SphericalChi2Test t([](float, const Vec2& u) { return std::optional<Vec3>(square_to_cosine_hemisphere(u)); },
                        pdf, o);
    Chi2Outcome r = t.run();
    EXPECT_FALSE(r.passed) << r.message;
}

TEST(Chi2Harness, test06_rejects_samples_outside_support) {
    // Uniform-sphere samples against a hemisphere pdf: samples where the pdf integral is 0.
    SphericalChi2Test t([](float, const Vec2& u) { return std::optional<Vec3>(square_to_uniform_sphere(u)); },
                        [](const Vec3& w) { return double(square_to_uniform_hemisphere_pdf(w)); },
                        small_options("self_support"));
    Chi2Outcome r = t.run();
    EXPECT_FALSE(r.passed);
    EXPECT_NE(r.message.find("pdf integral is 0"), std::string::npos) << r.message;
}

TEST(Chi2Harness, test07_missing_mass_is_detected) {
    // A sampler that silently drops 1 % of its samples while its pdf integrates to 1.
    SphericalChi2Test t(
        [](float u1, const Vec2& u) {
            if (u1 < 0.01f) return std::optional<Vec3>();
            return std::optional<Vec3>(square_to_cosine_hemisphere(u));
        },
        [](const Vec3& w) { return double(square_to_cosine_hemisphere_pdf(w)); },
        small_options("self_missing_mass"));
    Chi2Outcome r = t.run();
    EXPECT_FALSE(r.passed) << r.message;
    EXPECT_GT(std::fabs(r.total_z), 10.0) << r.message;
}

TEST(Chi2Harness, test08_scaled_pdf_is_detected) {
    // The pdf of a sampler that fails half of the time, but 3 % too large everywhere.
    SphericalChi2Test t(
        [](float u1, const Vec2& u) {
            if (u1 < 0.5f) return std::optional<Vec3>();
            return std::optional<Vec3>(square_to_cosine_hemisphere(u));
        },
        [](const Vec3& w) { return 0.5 * 1.03 * square_to_cosine_hemisphere_pdf(w); },
        small_options("self_scaled_pdf"));
    Chi2Outcome r = t.run();
    EXPECT_FALSE(r.passed) << r.message;
}

TEST(Chi2Harness, test09_smooth_shape_error_is_detected) {
    // A +-3 % tilt of the cosine pdf with unchanged total (cos^2 is uniform under the cosine
    // density, so the factor 0.97 + 0.06 cos^2 averages to 1): invisible in the total,
    // diluted in the fine table, caught by the coarse one. Full default resolution.
    Chi2Options o;
    o.name = "self_tilt";
    o.significance = 0.01;
    SphericalChi2Test t(
        [](float, const Vec2& u) { return std::optional<Vec3>(square_to_cosine_hemisphere(u)); },
        [](const Vec3& w) {
            return square_to_cosine_hemisphere_pdf(w) * (0.97 + 0.06 * double(w.z) * w.z);
        },
        o);
    Chi2Outcome r = t.run();
    EXPECT_FALSE(r.passed) << r.message;
    EXPECT_LT(r.coarse_p_value, 1e-6) << r.message;
}

}  // namespace
}  // namespace cmlt::test
