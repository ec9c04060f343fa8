/// \file PreviewSurfaceBsdf: lossless and reference white furnaces, the Dirac lobes (mirror,
/// Snell refraction, total internal reflection, Fresnel frequencies, pass-through, mixed
/// lobes) and a NaN/Inf sweep over parameters and directions.
#include "bsdf_test_util.h"
#include "preview_surface_checks.h"
#include "materials/fresnel.h"
#include "materials/preview_surface.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>

namespace cmlt::test {
namespace {

// ---------------------------------------------------------------------------------------------
// Lossless and reference white furnaces
// ---------------------------------------------------------------------------------------------

TEST(WhiteFurnace, test08_lambert_albedo_one_is_lossless) {
    PreviewSurfaceParams spec_wf = lambert(Spectrum(1.f));
    PreviewSurfaceParams ior_one = plastic(Spectrum(1.f), 0.5f);
    ior_one.ior = 1.f;  // metallic workflow, F0 = 0: no specular either
    for (const PreviewSurfaceParams& p : {spec_wf, ior_one}) {
        PreviewSurfaceBsdf bsdf(p);
        for (float side : {1.f, -1.f}) {
            for (float theta : {0.f, 45.f, 89.f}) {
                MeanEstimate e = furnace(bsdf, direction_deg(theta, 0.7f, side), 20000,
                                         TransportMode::Radiance, 7);
                EXPECT_NEAR(e.mean, 1.0, 1e-5);  // cosine sampling: every weight is exactly 1
                EXPECT_LT(e.std_error, 1e-6);
            }
        }
    }
}

TEST(WhiteFurnace, test09_smooth_dielectric_is_lossless) {
    // R + T = 1 per sample: reflection weight R/R = 1, refraction (1-R)/(1-R) = 1, times
    // 1/etap^2 in Radiance mode.
    for (float ior : {1.5f, 1.33f, 0.75f, 2.4f}) {
        PreviewSurfaceBsdf bsdf(glass(0.f, ior));
        for (float side : {1.f, -1.f}) {
            for (float theta : {0.f, 20.f, 45.f, 60.f, 85.f, 89.9f}) {
                Vec3 wo = direction_deg(theta, 0.7f, side);
                for (int i = 0; i < 2000; ++i) {
                    float ul = (i + 0.5f) / 2000.f;
                    for (TransportMode mode : {TransportMode::Radiance, TransportMode::Importance}) {
                        std::optional<PreviewSurfaceSample> s = bsdf.sample(wo, ul, Vec2(0.3f, 0.6f), mode);
                        ASSERT_TRUE(s.has_value()) << ior << " " << theta << " " << side;
                        ASSERT_TRUE(s->is_delta);
                        float expected = 1.f;
                        if (s->is_transmission && mode == TransportMode::Radiance)
                            expected = 1.f / (s->eta * s->eta);
                        ASSERT_NEAR(weight_of(*s).y, expected, 2e-5f * expected)
                            << "ior " << ior << " theta " << theta << " side " << side;
                    }
                }
            }
        }
    }
}

TEST(WhiteFurnace, test10_rough_conductor_matches_single_scattering_albedo) {
    // A white conductor (F = 1) loses exactly the single-scattering microfacet energy. Three
    // independent numbers must agree: (a) the albedo of the textbook GGX model integrated by
    // quadrature, (b) the same quadrature of bsdf.eval, (c) the Monte Carlo estimate from
    // bsdf.sample. The albedo must be < 1 and decrease with roughness.
    const int n_u = 1200, n_phi = 1200;
    std::vector<float> rough = {0.2f, 0.5f, 1.0f};
    for (float theta_o : {0.f, 45.f, 75.f}) {
        double previous = 2.0;
        for (float r : rough) {
            PreviewSurfaceBsdf bsdf(metal(Spectrum(1.f), r));
            const double alpha = double(r) * r;
            TextbookGgx ref{alpha};
            const double to = theta_o * k_pi_d / 180.0;
            const double wox = std::sin(to), woz = std::cos(to);
            const Vec3 wo(float(wox), 0.f, float(woz));
            // Quadrature over micro normals, with u = GGX projected-area CDF in theta_m:
            // D(m) cos(theta_m) dw_m = du dphi / (2 pi).
            double textbook = 0, from_eval = 0;
            for (int iu = 0; iu < n_u; ++iu) {
                double u = (iu + 0.5) / n_u;
                double tan_m = alpha * std::sqrt(u / (1 - u));
                double cos_m = 1 / std::sqrt(1 + tan_m * tan_m), sin_m = tan_m * cos_m;
                for (int ip = 0; ip < n_phi; ++ip) {
                    double phi = 2 * k_pi_d * (ip + 0.5) / n_phi;
                    double hx = sin_m * std::cos(phi), hy = sin_m * std::sin(phi), hz = cos_m;
                    double oh = wox * hx + woz * hz;
                    if (oh <= 0) continue;
                    double wix = 2 * oh * hx - wox, wiy = 2 * oh * hy, wiz = 2 * oh * hz - woz;
                    if (wiz <= 0) continue;
                    double cell = 1.0 / (double(n_u) * n_phi);  // du dphi / (2 pi)
                    // E = int D G2 (o.h) / cos_o dw_h
                    textbook += ref.g2(woz, wiz) * oh / (woz * cos_m) * cell;
                    // E = int f cos_i dw_i, dw_i = 4 (o.h) dw_h
                    Spectrum f = bsdf.eval(wo, Vec3(float(wix), float(wiy), float(wiz)),
                                           TransportMode::Radiance);
                    from_eval += f.y * wiz * 4 * oh / (ref.d(cos_m) * cos_m) * cell;
                }
            }
            MeanEstimate mc = furnace(bsdf, wo, 200000, TransportMode::Radiance, 50);
            if (verbose())
                std::cout << "conductor r " << r << " theta_o " << theta_o << ": textbook "
                          << textbook << ", eval quadrature " << from_eval << ", MC " << mc.mean
                          << " +- " << mc.std_error << "\n";
            EXPECT_NEAR(from_eval, textbook, 2e-3) << "r " << r << " theta_o " << theta_o;
            EXPECT_NEAR(mc.mean, textbook, 4.5 * mc.std_error + 2e-3)
                << "r " << r << " theta_o " << theta_o;
            EXPECT_LT(textbook, 1.0);
            EXPECT_GT(textbook, 0.25);
            if (theta_o == 0.f && r == 1.f) {
                // alpha = 1, normal incidence: D = 1/pi, G2 = 2 cos_i / (1 + cos_i), and the
                // integral has the closed form 1 - ln 2.
                EXPECT_NEAR(textbook, 1.0 - std::log(2.0), 1e-4);
            }
            EXPECT_LT(textbook, previous) << "albedo should decrease with roughness";
            previous = textbook;
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Dirac lobes
// ---------------------------------------------------------------------------------------------

TEST(Delta, test11_mirror_metal_returns_fresnel_weighted_mirror_direction) {
    const Spectrum f0(0.95f, 0.64f, 0.54f);
    PreviewSurfaceBsdf bsdf(metal(f0, 0.f));
    ASSERT_TRUE(bsdf.is_pure_delta());
    for (float side : {1.f, -1.f}) {
        for (float theta : {0.f, 40.f, 80.f, 89.9f}) {
            Vec3 wo = direction_deg(theta, 0.7f, side);
            Vec3 mirror(-wo.x, -wo.y, wo.z);
            float c = std::fabs(wo.z);
            Spectrum fresnel = f0 + (Spectrum(1.f) - f0) * std::pow(1.f - c, 5.f);  // Schlick
            for (float ul : {0.f, 0.5f, 0.999f}) {
                std::optional<PreviewSurfaceSample> s = bsdf.sample(wo, ul, Vec2(0.2f, 0.9f), TransportMode::Radiance);
                ASSERT_TRUE(s.has_value());
                EXPECT_TRUE(s->is_delta);
                EXPECT_FALSE(s->is_transmission);
                EXPECT_EQ(s->wi, mirror);
                EXPECT_EQ(s->pdf, 1.f);
                EXPECT_TRUE(near_rel(weight_of(*s), fresnel, 1e-5f, 1e-7f))
                    << str(weight_of(*s)) << " vs " << str(fresnel);
            }
            EXPECT_EQ(bsdf.eval(wo, mirror, TransportMode::Radiance), Spectrum(0.f));
            EXPECT_EQ(bsdf.pdf(wo, mirror), 0.f);
        }
    }
}

TEST(Delta, test12_smooth_glass_refraction_obeys_snell) {
    PreviewSurfaceBsdf bsdf(glass(0.f, 1.5f));
    struct Case {
        float theta, side, eta;
    };
    for (Case c : {Case{50.f, 1.f, 1.5f}, Case{10.f, 1.f, 1.5f}, Case{30.f, -1.f, 1.f / 1.5f},
                   Case{41.f, -1.f, 1.f / 1.5f}}) {
        Vec3 wo = direction_deg(c.theta, 0.7f, c.side);
        // u_lobe close to 1 selects refraction whenever R < 1.
        std::optional<PreviewSurfaceSample> s = bsdf.sample(wo, 0.9999f, Vec2(0.5f, 0.5f), TransportMode::Radiance);
        ASSERT_TRUE(s.has_value());
        EXPECT_TRUE(s->is_delta);
        EXPECT_TRUE(s->is_transmission);
        EXPECT_NEAR(s->eta, c.eta, 1e-6f);
        EXPECT_LT(s->wi.z * wo.z, 0.f);
        float sin_o = std::sqrt(wo.x * wo.x + wo.y * wo.y);
        float sin_i = std::sqrt(s->wi.x * s->wi.x + s->wi.y * s->wi.y);
        EXPECT_NEAR(sin_o, c.eta * sin_i, 2e-6f) << "Snell: sin(theta_o) = eta sin(theta_t)";
        EXPECT_NEAR(wo.x * s->wi.y - wo.y * s->wi.x, 0.f, 1e-6f);  // plane of incidence
        EXPECT_LE(wo.x * s->wi.x + wo.y * s->wi.y, 0.f);           // opposite azimuth
        float fr = fresnel_dielectric(wo.z, 1.5f);
        EXPECT_NEAR(s->pdf, 1.f - fr, 1e-6f);
        EXPECT_NEAR(weight_of(*s).x, 1.f / (c.eta * c.eta), 1e-5f);
        std::optional<PreviewSurfaceSample> si = bsdf.sample(wo, 0.9999f, Vec2(0.5f, 0.5f), TransportMode::Importance);
        ASSERT_TRUE(si.has_value());
        EXPECT_NEAR(weight_of(*si).x, 1.f, 1e-5f);
    }
}

TEST(Delta, test13_total_internal_reflection_above_critical_angle) {
    PreviewSurfaceBsdf bsdf(glass(0.f, 1.5f));
    const float critical = std::asin(1.f / 1.5f) * 180.f / k_pi;  // 41.81 degrees
    for (float theta : {critical + 0.1f, 50.f, 70.f, 89.f}) {
        Vec3 wo = direction_deg(theta, 0.7f, -1.f);
        for (int i = 0; i < 100; ++i) {
            std::optional<PreviewSurfaceSample> s =
                bsdf.sample(wo, (i + 0.5f) / 100.f, Vec2(0.5f, 0.5f), TransportMode::Radiance);
            ASSERT_TRUE(s.has_value());
            EXPECT_TRUE(s->is_delta);
            EXPECT_FALSE(s->is_transmission) << "refraction beyond the critical angle " << theta;
            EXPECT_EQ(s->wi, Vec3(-wo.x, -wo.y, wo.z));
            EXPECT_NEAR(weight_of(*s).x, 1.f, 1e-6f);
        }
    }
    // Just below the critical angle refraction is still possible.
    Vec3 wo = direction_deg(critical - 0.5f, 0.7f, -1.f);
    std::optional<PreviewSurfaceSample> s = bsdf.sample(wo, 0.99999f, Vec2(0.5f, 0.5f), TransportMode::Radiance);
    ASSERT_TRUE(s.has_value());
    EXPECT_TRUE(s->is_transmission);
}

TEST(Delta, test14_reflection_frequency_is_fresnel) {
    // Stratified u_lobe: the fraction of reflections equals R to within 1/n.
    PreviewSurfaceBsdf bsdf(glass(0.f, 1.5f));
    const int n = 20000;
    for (float side : {1.f, -1.f}) {
        for (float theta : {0.f, 30.f, 60.f, 85.f}) {
            Vec3 wo = direction_deg(theta, 0.7f, side);
            int reflections = 0;
            for (int i = 0; i < n; ++i) {
                std::optional<PreviewSurfaceSample> s =
                    bsdf.sample(wo, (i + 0.5f) / n, Vec2(0.5f, 0.5f), TransportMode::Importance);
                ASSERT_TRUE(s.has_value());
                reflections += s->is_transmission ? 0 : 1;
            }
            float fr = fresnel_dielectric(wo.z, 1.5f);
            EXPECT_NEAR(double(reflections) / n, fr, 1.5 / n) << theta << " " << side;
        }
    }
}

TEST(Delta, test15_ior_one_is_pure_pass_through) {
    for (float roughness : {0.f, 0.5f, 1.f}) {
        PreviewSurfaceBsdf bsdf(glass(roughness, 1.f));
        ASSERT_TRUE(bsdf.is_pure_delta());
        for (float side : {1.f, -1.f}) {
            for (float theta : {0.f, 45.f, 89.99f}) {
                Vec3 wo = direction_deg(theta, 0.7f, side);
                for (TransportMode mode : {TransportMode::Radiance, TransportMode::Importance}) {
                    std::optional<PreviewSurfaceSample> s = bsdf.sample(wo, 0.37f, Vec2(0.1f, 0.8f), mode);
                    ASSERT_TRUE(s.has_value());
                    EXPECT_TRUE(s->is_delta);
                    EXPECT_TRUE(s->is_transmission);
                    EXPECT_EQ(s->wi, -wo);
                    EXPECT_EQ(s->eta, 1.f);
                    EXPECT_NEAR(weight_of(*s).x, 1.f, 1e-6f);
                }
                EXPECT_EQ(bsdf.eval(wo, -wo, TransportMode::Radiance), Spectrum(0.f));
                EXPECT_EQ(bsdf.pdf(wo, -wo), 0.f);
            }
        }
    }
}

TEST(Delta, test16_mixed_delta_and_smooth_lobes) {
    // Smooth plastic: a Dirac mirror (0.04 Schlick) over a Lambert base. Delta samples carry
    // only the mirror; non-delta samples only the diffuse; together an unbiased, <= 1 albedo.
    PreviewSurfaceBsdf bsdf(plastic(Spectrum(0.5f), 0.f));
    Vec3 wo = direction_deg(60.f);
    int deltas = 0, smooth = 0;
    TestRng rng(21);
    for (int i = 0; i < 20000; ++i) {
        std::optional<PreviewSurfaceSample> s = bsdf.sample(wo, rng.get1d(), rng.get2d(), TransportMode::Radiance);
        ASSERT_TRUE(s.has_value());
        if (s->is_delta) {
            ++deltas;
            EXPECT_EQ(s->wi, Vec3(-wo.x, -wo.y, wo.z));
        } else {
            ++smooth;
        }
    }
    EXPECT_GT(deltas, 0);
    EXPECT_GT(smooth, 0);
    MeanEstimate e = furnace(bsdf, wo, 100000, TransportMode::Radiance, 3);
    EXPECT_LT(e.mean, 1.0);
}

// ---------------------------------------------------------------------------------------------
// Robustness
// ---------------------------------------------------------------------------------------------

TEST(Robustness, test17_no_nan_or_inf_anywhere) {
    std::vector<Vec3> dirs;
    for (float z : {1.f, 0.5f, 1e-4f, 1e-8f, 0.f, -1e-8f, -1e-4f, -0.5f, -1.f}) {
        float r = safe_sqrt(1.f - z * z);
        dirs.emplace_back(r * 0.6f, r * 0.8f, z);
    }
    dirs.emplace_back(1.f, 0.f, 0.f);
    dirs.emplace_back(0.f, 0.f, 1.f);
    dirs.emplace_back(1e-20f, 0.f, 1.f);
    dirs.emplace_back(0.f, 1.f, 1e-30f);  // denormal-range cosine
    const float k_max_u = k_one_minus_eps;
    // 1.0 is outside the documented [0, 1) but must not produce NaN either.
    const std::vector<float> u_lobes = {0.f, 0.3f, 0.7f, k_max_u, 1.f};
    const std::vector<Vec2> us = {{0.f, 0.f},         {0.5f, 0.5f},     {k_max_u, k_max_u},
                                  {0.999f, 0.001f},   {0.f, k_max_u},   {1.f, 1.f}};

    long calls = 0, samples_ok = 0;
    for (float roughness : {0.f, 1e-4f, 0.02f, 0.2f, 1.f})
    for (float metallic : {0.f, 1.f})
    for (float opacity : {0.f, 0.5f, 1.f})
    for (float ior : {1.f, 1.0005f, 1.5f, 0.6f, 0.f})
    for (float clearcoat : {0.f, 1.f})
    for (float cc_roughness : {0.f, 0.5f})
    for (float diffuse : {0.f, 1.f})
    for (int workflow : {0, 1, 2}) {
        PreviewSurfaceParams p;
        p.diffuse = Spectrum(diffuse);
        p.use_specular_workflow = workflow > 0;
        p.specular = Spectrum(workflow == 2 ? 1.f : 0.f);
        p.metallic = metallic;
        p.roughness = roughness;
        p.clearcoat = clearcoat;
        p.clearcoat_roughness = cc_roughness;
        p.opacity = opacity;
        p.ior = ior;
        PreviewSurfaceBsdf bsdf(p);
        Spectrum albedo = bsdf.albedo_estimate();
        ASSERT_TRUE(is_finite(albedo));
        for (const Vec3& wo : dirs) {
            for (TransportMode mode : {TransportMode::Radiance, TransportMode::Importance}) {
                for (const Vec3& wi : dirs) {
                    for (const Vec3& w : {wi, -wi}) {
                        Spectrum f = bsdf.eval(wo, w, mode);
                        float pdf = bsdf.pdf(wo, w);
                        ++calls;
                        ASSERT_TRUE(is_finite(f) && min_component(f) >= 0.f)
                            << "eval " << str(f) << " wo " << str(wo) << " wi " << str(w);
                        ASSERT_TRUE(std::isfinite(pdf) && pdf >= 0.f) << "pdf " << pdf;
                    }
                }
                for (float ul : u_lobes) {
                    for (const Vec2& u : us) {
                        std::optional<PreviewSurfaceSample> s = bsdf.sample(wo, ul, u, mode);
                        ++calls;
                        if (!s) continue;
                        ++samples_ok;
                        ASSERT_TRUE(is_finite(s->f) && min_component(s->f) >= 0.f)
                            << "sample f " << str(s->f) << " wo " << str(wo);
                        ASSERT_TRUE(std::isfinite(s->pdf) && s->pdf > 0.f) << s->pdf;
                        ASSERT_TRUE(is_finite(s->wi) && std::fabs(length(s->wi) - 1.f) < 1e-3f)
                            << str(s->wi);
                        ASSERT_TRUE(std::isfinite(s->eta) && s->eta > 0.f);
                        ASSERT_TRUE(is_finite(weight_of(*s))) << str(weight_of(*s));
                    }
                }
            }
        }
    }
    EXPECT_GT(samples_ok, calls / 100);
    if (verbose()) std::cout << calls << " calls, " << samples_ok << " valid samples\n";
}

}  // namespace
}  // namespace cmlt::test
