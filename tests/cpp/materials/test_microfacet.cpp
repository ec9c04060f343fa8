/// \file Unit tests of fresnel.h and microfacet.h against closed forms and textbook formulas.
#include "bsdf_test_util.h"  // TextbookGgx
#include "direction_chi2.h"            // adaptive_simpson
#include "materials/fresnel.h"
#include "materials/microfacet.h"

#include <gtest/gtest.h>

#include <cmath>

namespace cmlt::test {
namespace {

constexpr double k_pi_d = 3.14159265358979323846;

TEST(Fresnel, test01_dielectric_known_values) {
    EXPECT_NEAR(fresnel_dielectric(1.f, 1.5f), 0.04f, 1e-6f);
    EXPECT_NEAR(fresnel_dielectric(-1.f, 1.5f), 0.04f, 1e-6f);  // same from inside at normal
    EXPECT_EQ(fresnel_dielectric(0.f, 1.5f), 1.f);               // grazing from outside
    EXPECT_EQ(fresnel_dielectric(0.3f, 1.f), 0.f);               // no interface
    EXPECT_EQ(fresnel_dielectric(0.f, 1.f), 0.f);                // ... even at grazing (no 0/0)
    // Total internal reflection from inside above the critical angle asin(1/1.5).
    float crit = std::asin(1.f / 1.5f);
    EXPECT_EQ(fresnel_dielectric(-std::cos(crit + 0.01f), 1.5f), 1.f);
    EXPECT_LT(fresnel_dielectric(-std::cos(crit - 0.01f), 1.5f), 1.f);
    // Brewster angle: the parallel component vanishes, F = r_perp^2 / 2.
    float tb = std::atan(1.5f), ct = std::cos(std::asin(std::sin(tb) / 1.5f));
    float r_perp = (std::cos(tb) - 1.5f * ct) / (std::cos(tb) + 1.5f * ct);
    EXPECT_NEAR(fresnel_dielectric(std::cos(tb), 1.5f), 0.5f * r_perp * r_perp, 1e-6f);
    // Reciprocity across the interface: F(outside, theta_i) == F(inside, theta_t).
    for (float ti : {0.1f, 0.5f, 1.0f, 1.4f}) {
        float tt = std::asin(std::sin(ti) / 1.5f);
        EXPECT_NEAR(fresnel_dielectric(std::cos(ti), 1.5f), fresnel_dielectric(-std::cos(tt), 1.5f),
                    1e-5f);
    }
    EXPECT_NEAR(schlick_f0_from_ior(1.5f), 0.04f, 1e-7f);
}

TEST(Fresnel, test02_refract_obeys_snell_and_reports_tir) {
    Vec3 n(0.f, 0.f, 1.f);
    Vec3 wi = normalize(Vec3(0.6f, 0.2f, 0.5f));
    float etap = 0.f;
    Vec3 wt;
    ASSERT_TRUE(refract(wi, n, 1.5f, &etap, &wt));
    EXPECT_EQ(etap, 1.5f);
    EXPECT_NEAR(length(wt), 1.f, 1e-6f);
    float sin_i = std::sqrt(1.f - wi.z * wi.z), sin_t = std::sqrt(1.f - wt.z * wt.z);
    EXPECT_NEAR(sin_i, 1.5f * sin_t, 1e-5f);
    EXPECT_LT(wt.z, 0.f);
    EXPECT_NEAR(wt.x * wi.y - wt.y * wi.x, 0.f, 1e-6f);  // same plane of incidence
    EXPECT_LT(wt.x * wi.x, 0.f);                         // opposite azimuth
    // From inside at 60 degrees: beyond the critical angle (41.8 degrees).
    Vec3 inside(std::sin(1.047f), 0.f, -std::cos(1.047f));
    EXPECT_FALSE(refract(inside, n, 1.5f, &etap, &wt));
}

TEST(Microfacet, test01_stable_forms_match_textbook) {
    for (float alpha : {0.001f, 0.04f, 0.25f, 1.f}) {
        GgxDistribution ggx(alpha);
        TextbookGgx ref{alpha};
        for (float co : {1.f, 0.8f, 0.3f, 0.05f, 1e-3f}) {
            for (float ci : {0.9f, 0.5f, 0.01f}) {
                Vec3 wo(std::sqrt(1 - co * co), 0.f, co), wi(0.f, std::sqrt(1 - ci * ci), ci);
                double g2 = 1.0 / (1.0 + ref.lambda(co) + ref.lambda(ci));
                EXPECT_NEAR(ggx.g2(wo, wi), g2, 1e-5 * std::max(1.0, g2));
                double g2cc = g2 / (double(co) * ci);
                EXPECT_NEAR(ggx.g2_over_cos2(wo, wi), g2cc, 1e-5 * g2cc);
                double g1 = 1.0 / (1.0 + ref.lambda(co));
                EXPECT_NEAR(ggx.g1(wo), g1, 1e-5);
                EXPECT_NEAR(ggx.g1_over_cos(wo), g1 / co, 1e-5 * g1 / co);
                EXPECT_NEAR(ggx.lambda(wo), ref.lambda(co), 1e-4 * std::max(1.0, ref.lambda(co)));
            }
            double dm = ref.d(co);
            Vec3 wm(std::sqrt(1 - co * co), 0.f, co);
            EXPECT_NEAR(ggx.d(wm), dm, 1e-4 * dm + 1e-7) << alpha << " " << co;
        }
        // Horizon: finite, and G1 = 0 exactly.
        Vec3 h(1.f, 0.f, 0.f);
        EXPECT_EQ(ggx.g1(h), 0.f);
        EXPECT_TRUE(std::isfinite(ggx.g1_over_cos(h)));
        EXPECT_TRUE(std::isfinite(ggx.g2_over_cos2(h, Vec3(0.f, 0.f, 1.f))));
    }
}

TEST(Microfacet, test02_distribution_and_visible_normals_are_normalised) {
    for (float alpha : {0.05f, 0.3f, 1.f}) {
        GgxDistribution ggx(alpha);
        // Integral of D(wm) cos(theta_m) over the hemisphere (phi-symmetric).
        auto projected = [&](double t) {
            Vec3 wm(float(std::sin(t)), 0.f, float(std::cos(t)));
            return 2 * k_pi_d * ggx.d(wm) * std::cos(t) * std::sin(t);
        };
        EXPECT_NEAR(adaptive_simpson(projected, 0, k_pi_d / 2, 1e-9, 16, 6), 1.0, 1e-4) << alpha;
        // The visible-normal density integrates to 1 for any view direction (Heitz 2014 eq. 17).
        // Quadrature in the variables of the GGX projected-area CDF, where
        // D(m) cos(theta_m) dw_m = du dphi / (2 pi), so the peak of D costs nothing; then
        // u = 1 - v^2 removes the integrable (1 - u)^(-1/2) growth of the integrand.
        const int n = 500;
        for (float theta_o : {0.f, 0.7f, 1.4f, 1.55f}) {
            Vec3 wo(std::sin(theta_o), 0.f, std::cos(theta_o));
            double total = 0;
            for (int iu = 0; iu < n; ++iu) {
                double v = (iu + 0.5) / n, u = 1 - v * v, tan_m = alpha * std::sqrt(u) / v;
                double cos_m = 1 / std::sqrt(1 + tan_m * tan_m), sin_m = tan_m * cos_m;
                for (int ip = 0; ip < n; ++ip) {
                    double phi = 2 * k_pi_d * (ip + 0.5) / n;
                    Vec3 wm(float(sin_m * std::cos(phi)), float(sin_m * std::sin(phi)), float(cos_m));
                    double d = ggx.d(wm);
                    if (d > 0) total += 2 * v * ggx.visible_pdf(wo, wm) / (d * cos_m) / (double(n) * n);
                }
            }
            EXPECT_NEAR(total, 1.0, 2e-3) << "alpha " << alpha << " theta_o " << theta_o;
        }
    }
}

TEST(Microfacet, test03_sampled_normals_face_the_viewer) {
    GgxDistribution ggx(0.5f);
    for (float side : {1.f, -1.f}) {
        Vec3 wo = normalize(Vec3(0.7f, -0.2f, side * 0.1f));
        for (int i = 0; i < 64; ++i) {
            for (int j = 0; j < 64; ++j) {
                Vec2 u((i + 0.5f) / 64.f, (j + 0.5f) / 64.f);
                Vec3 wm = ggx.sample_visible(wo, u);
                ASSERT_GT(wm.z, 0.f);
                ASSERT_NEAR(length(wm), 1.f, 1e-5f);
                ASSERT_GT(dot(wo, wm) * wo.z, 0.f) << "back-facing micro normal sampled";
            }
        }
    }
}

}  // namespace
}  // namespace cmlt::test
