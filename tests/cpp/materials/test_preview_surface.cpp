/// \file PreviewSurfaceBsdf: sample/eval/pdf consistency, reciprocity, white furnace, Dirac
/// lobes and a NaN/Inf sweep. The chi^2 tests are in preview_surface_chi2_test.cpp.
#include "bsdf_test_util.h"
#include "materials/fresnel.h"
#include "materials/preview_surface.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>

namespace cmlt::test {
namespace {

constexpr double k_pi_d = 3.14159265358979323846;

/// Print furnace values etc. when CMLT_TEST_VERBOSE is set (never needed to pass).
bool verbose() { return std::getenv("CMLT_TEST_VERBOSE") != nullptr; }

std::vector<NamedParams> all_configurations() {
    std::vector<NamedParams> all = smooth_configurations();
    for (NamedParams& p : delta_configurations()) all.push_back(p);
    for (NamedParams& p : energy_stress_configurations()) all.push_back(p);
    return all;
}

/// Outgoing directions used by the per-configuration tests: both sides, normal to grazing.
std::vector<Vec3> test_outgoing_directions() {
    std::vector<Vec3> dirs;
    for (float side : {1.f, -1.f})
        for (float theta : {0.f, 35.f, 70.f, 88.f, 89.9f}) dirs.push_back(direction_deg(theta, 0.7f, side));
    return dirs;
}

bool near_rel(float a, float b, float rel, float abs_tol) {
    return std::fabs(a - b) <= rel * std::max(std::fabs(a), std::fabs(b)) + abs_tol;
}

bool near_rel(const Spectrum& a, const Spectrum& b, float rel, float abs_tol) {
    return near_rel(a.x, b.x, rel, abs_tol) && near_rel(a.y, b.y, rel, abs_tol) &&
           near_rel(a.z, b.z, rel, abs_tol);
}

std::string str(const Vec3& v) {
    std::ostringstream os;
    os.precision(9);
    os << "(" << v.x << ", " << v.y << ", " << v.z << ")";
    return os.str();
}

Spectrum weight_of(const PreviewSurfaceSample& s) { return s.f * (std::fabs(s.wi.z) / s.pdf); }

// ---------------------------------------------------------------------------------------------
// Construction
// ---------------------------------------------------------------------------------------------

TEST(PreviewSurface, test01_parameters_are_sanitised) {
    PreviewSurfaceParams p;
    p.diffuse = Spectrum(NAN, 2.f, -1.f);
    p.specular = Spectrum(INFINITY, 0.5f, 0.5f);
    p.metallic = NAN;
    p.roughness = 7.f;
    p.clearcoat = INFINITY;
    p.clearcoat_roughness = -1.f;
    p.opacity = -3.f;
    p.ior = 0.f;
    PreviewSurfaceBsdf bsdf(p);
    const PreviewSurfaceParams& q = bsdf.params();
    EXPECT_EQ(q.diffuse, Spectrum(0.18f, 1.f, 0.f));
    EXPECT_EQ(q.specular, Spectrum(0.f, 0.5f, 0.5f));
    EXPECT_EQ(q.metallic, 0.f);
    EXPECT_EQ(q.roughness, 1.f);
    EXPECT_EQ(q.clearcoat, 0.f);
    EXPECT_EQ(q.clearcoat_roughness, 0.f);
    EXPECT_EQ(q.opacity, 0.f);
    EXPECT_EQ(q.ior, 1.f);
    p.ior = 40.f;
    EXPECT_EQ(PreviewSurfaceBsdf(p).params().ior, 5.f);
}

TEST(PreviewSurface, test02_lobe_flags) {
    const Spectrum copper(0.95f, 0.64f, 0.54f);
    struct Expect {
        const char* name;
        PreviewSurfaceParams p;
        bool has_delta, pure_delta;
    };
    PreviewSurfaceParams black_metal = metal(Spectrum(0.f), 0.5f);
    const Expect cases[] = {
        {"lambert", lambert(Spectrum(0.5f)), false, false},
        {"rough metal", metal(copper, 0.5f), false, false},
        {"mirror metal", metal(copper, 0.f), true, true},
        {"mirror below threshold", metal(copper, 0.03f), true, true},
        {"just rough", metal(copper, 0.035f), false, false},
        {"smooth plastic", plastic(Spectrum(0.5f), 0.f), true, false},
        {"smooth glass", glass(0.f, 1.5f), true, true},
        {"rough glass", glass(0.3f, 1.5f), false, false},
        {"pass-through", glass(0.8f, 1.f), true, true},
        {"black metal", black_metal, false, false},
        {"smooth clearcoat over rough", with_clearcoat(plastic(Spectrum(0.5f), 0.5f), 1.f, 0.f), true,
         false},
    };
    for (const Expect& e : cases) {
        PreviewSurfaceBsdf b(e.p);
        EXPECT_EQ(b.has_delta(), e.has_delta) << e.name;
        EXPECT_EQ(b.is_pure_delta(), e.pure_delta) << e.name;
    }
    // Metallic 1 with black diffuse: no lobe at all -> black, nothing to sample, no NaN.
    PreviewSurfaceBsdf black(black_metal);
    Vec3 wo = direction_deg(30.f), wi = direction_deg(40.f, 2.f);
    EXPECT_EQ(black.eval(wo, wi, TransportMode::Radiance), Spectrum(0.f));
    EXPECT_EQ(black.pdf(wo, wi), 0.f);
    EXPECT_FALSE(black.sample(wo, 0.5f, Vec2(0.5f, 0.5f), TransportMode::Radiance).has_value());
    EXPECT_EQ(black.albedo_estimate(), Spectrum(0.f));
}

TEST(PreviewSurface, test03_albedo_estimate_is_sensible) {
    // Lambert: exactly its colour; white mirror metal: 1; clear glass: 1; all within [0, 1].
    EXPECT_EQ(PreviewSurfaceBsdf(lambert(Spectrum(0.3f, 0.6f, 0.9f))).albedo_estimate(),
              Spectrum(0.3f, 0.6f, 0.9f));
    Spectrum m = PreviewSurfaceBsdf(metal(Spectrum(1.f), 0.3f)).albedo_estimate();
    EXPECT_NEAR(m.x, 1.f, 1e-6f);
    Spectrum g = PreviewSurfaceBsdf(glass(0.f, 1.5f)).albedo_estimate();
    EXPECT_NEAR(g.y, 1.f, 1e-6f);
    for (const NamedParams& c : all_configurations()) {
        Spectrum a = PreviewSurfaceBsdf(c.params).albedo_estimate();
        EXPECT_TRUE(is_finite(a) && min_component(a) >= 0.f && max_component(a) <= 1.f) << c.name;
    }
}

// ---------------------------------------------------------------------------------------------
// Per-configuration tests
// ---------------------------------------------------------------------------------------------

class PreviewSurfaceConfig : public ::testing::TestWithParam<NamedParams> {};

TEST_P(PreviewSurfaceConfig, test04_sample_matches_eval_and_pdf) {
    const PreviewSurfaceBsdf bsdf(GetParam().params);
    TestRng rng(11, 1);
    int checked = 0;
    for (const Vec3& wo : test_outgoing_directions()) {
        for (TransportMode mode : {TransportMode::Radiance, TransportMode::Importance}) {
            for (int i = 0; i < 2000; ++i) {
                float ul = rng.get1d();
                Vec2 u = rng.get2d();
                std::optional<PreviewSurfaceSample> s = bsdf.sample(wo, ul, u, mode);
                if (!s) continue;
                ASSERT_TRUE(is_finite(s->f) && std::isfinite(s->pdf) && s->pdf > 0.f)
                    << "wo " << str(wo);
                ASSERT_NEAR(length(s->wi), 1.f, 1e-4f);
                ASSERT_EQ(s->is_transmission, s->wi.z * wo.z < 0.f);
                const float ior = bsdf.params().ior;
                const bool pass_through = std::fabs(ior - 1.f) < 1e-3f;
                float expected_eta = s->is_transmission && !pass_through
                                         ? (wo.z > 0.f ? ior : 1.f / ior)
                                         : 1.f;
                ASSERT_NEAR(s->eta, expected_eta, 1e-6f);
                ASSERT_TRUE(is_finite(weight_of(*s)));
                if (s->is_delta) continue;
                Spectrum f = bsdf.eval(wo, s->wi, mode);
                float pdf = bsdf.pdf(wo, s->wi);
                ASSERT_TRUE(near_rel(s->f, f, 1e-5f, 0.f))
                    << "wo " << str(wo) << " wi " << str(s->wi) << " sample f " << str(s->f)
                    << " eval " << str(f);
                ASSERT_TRUE(near_rel(s->pdf, pdf, 1e-5f, 0.f))
                    << "wo " << str(wo) << " wi " << str(s->wi) << " sample pdf " << s->pdf
                    << " pdf() " << pdf;
                // eval/pdf == sample f/pdf (the quantity integrators use)
                Spectrum a = f / pdf, b = s->f / s->pdf;
                ASSERT_TRUE(near_rel(a, b, 1e-5f, 0.f));
                ++checked;
            }
        }
    }
    if (!bsdf.is_pure_delta()) {
        EXPECT_GT(checked, 1000);
    }
}

TEST_P(PreviewSurfaceConfig, test05_pdf_covers_eval) {
    // Wherever a non-delta lobe has a value, the sampler must be able to reach it.
    const PreviewSurfaceBsdf bsdf(GetParam().params);
    TestRng rng(12, 2);
    int nonzero = 0;
    for (int i = 0; i < 200000; ++i) {
        Vec3 wo = rng.uniform_sphere(), wi = rng.uniform_sphere();
        Spectrum f = bsdf.eval(wo, wi, TransportMode::Radiance);
        float pdf = bsdf.pdf(wo, wi);
        ASSERT_TRUE(is_finite(f) && std::isfinite(pdf) && min_component(f) >= 0.f && pdf >= 0.f);
        if (max_component(f) > 0.f) {
            ++nonzero;
            ASSERT_GT(pdf, 0.f) << "wo " << str(wo) << " wi " << str(wi) << " f " << str(f);
        }
    }
    if (bsdf.is_pure_delta()) {
        EXPECT_EQ(nonzero, 0);
    }
}

TEST_P(PreviewSurfaceConfig, test06_reciprocity) {
    // Reflection: f(wo, wi) = f(wi, wo). Transmission is adjoint (Veach 1997, eq. 5.14):
    // f_radiance(wo, wi) = f_importance(wi, wo).
    const PreviewSurfaceBsdf bsdf(GetParam().params);
    TestRng rng(13, 3);
    const int n = 100000;
    int skipped = 0;
    for (int i = 0; i < n; ++i) {
        Vec3 wo = rng.uniform_sphere(), wi = rng.uniform_sphere();
        bool reflection = wo.z * wi.z > 0.f;
        if (!reflection) {
            // Near the critical angle the Fresnel transmittance is ill-conditioned (cos_t =
            // sqrt(1 - sin_t^2) cancels), so 1-ulp differences between the two generalised
            // half vectors change 1 - F by ~1e-3. Skip those micro-configurations.
            double ior = bsdf.params().ior, etap = wo.z > 0 ? ior : 1.0 / ior;
            double mx = wo.x + etap * wi.x, my = wo.y + etap * wi.y, mz = wo.z + etap * wi.z;
            double ml = std::sqrt(mx * mx + my * my + mz * mz);
            double om = std::fabs(wo.x * mx + wo.y * my + wo.z * mz) / ml;
            double im = std::fabs(wi.x * mx + wi.y * my + wi.z * mz) / ml;
            if (std::min(om, im) < 0.02) {
                ++skipped;
                continue;
            }
        }
        Spectrum a = bsdf.eval(wo, wi, TransportMode::Radiance);
        Spectrum b = reflection ? bsdf.eval(wi, wo, TransportMode::Radiance)
                                : bsdf.eval(wi, wo, TransportMode::Importance);
        // Rounding differs between the two half vectors; sharp lobes amplify it slightly.
        ASSERT_TRUE(near_rel(a, b, 2e-3f, 1e-6f))
            << (reflection ? "reflection" : "transmission") << " wo " << str(wo) << " wi "
            << str(wi) << ": " << str(a) << " vs " << str(b);
    }
    EXPECT_LT(skipped, n / 50);
}

struct MeanEstimate {
    double mean = 0, std_error = 0;
};

/// E[f |cos wi| / pdf] with `n` samples (failed samples count as 0): the directional albedo.
/// In Radiance mode the 1/etap^2 factor of refraction is undone (multiplied by eta^2).
MeanEstimate furnace(const PreviewSurfaceBsdf& bsdf, const Vec3& wo, int n, TransportMode mode,
                     uint32_t stream, int channel = 1) {
    TestRng rng(14, stream);
    double sum = 0, sum2 = 0;
    for (int i = 0; i < n; ++i) {
        float ul = rng.get1d();
        Vec2 u = rng.get2d();
        std::optional<PreviewSurfaceSample> s = bsdf.sample(wo, ul, u, mode);
        double w = 0;
        if (s) {
            w = weight_of(*s)[channel];
            if (mode == TransportMode::Radiance && s->is_transmission) w *= double(s->eta) * s->eta;
        }
        sum += w;
        sum2 += w * w;
    }
    MeanEstimate e;
    e.mean = sum / n;
    e.std_error = std::sqrt(std::max(0.0, sum2 / n - e.mean * e.mean) / (n - 1));
    return e;
}

TEST_P(PreviewSurfaceConfig, test07_white_furnace_at_most_one) {
    const PreviewSurfaceBsdf bsdf(GetParam().params);
    uint32_t stream = 100;
    for (const Vec3& wo : test_outgoing_directions()) {
        for (TransportMode mode : {TransportMode::Importance, TransportMode::Radiance}) {
            for (int channel = 0; channel < 3; ++channel) {
                MeanEstimate e = furnace(bsdf, wo, 40000, mode, stream++, channel);
                if (verbose() && mode == TransportMode::Importance && channel == 1)
                    std::cout << GetParam().name << " theta_o " << std::acos(wo.z) * 180 / k_pi_d
                              << ": albedo " << e.mean << " +- " << e.std_error << "\n";
                // 4.5 standard errors: ~1e-5 false-alarm rate per check.
                EXPECT_LE(e.mean - 4.5 * e.std_error, 1.0 + 1e-5)
                    << GetParam().name << " wo " << str(wo) << " channel " << channel
                    << ": albedo " << e.mean << " +- " << e.std_error;
            }
        }
    }
}

/// The configurations with a Dirac lobe (test08 has nothing to check on the others).
std::vector<NamedParams> dirac_configurations() {
    std::vector<NamedParams> out;
    for (const NamedParams& c : all_configurations())
        if (PreviewSurfaceBsdf(c.params).has_delta()) out.push_back(c);
    return out;
}

class PreviewSurfaceDiracConfig : public ::testing::TestWithParam<NamedParams> {};

TEST_P(PreviewSurfaceDiracConfig, test08_delta_pdf_is_its_discrete_probability) {
    // A Dirac sample reports pdf = the probability of sampling exactly that direction. Check
    // it against the observed frequency of each distinct Dirac direction (binomial, 5 sigma).
    const PreviewSurfaceBsdf bsdf(GetParam().params);
    ASSERT_TRUE(bsdf.has_delta());
    TestRng rng(15, 4);
    const int n = 40000;
    for (const Vec3& wo : test_outgoing_directions()) {
        struct Seen {
            Vec3 wi;
            float pdf;
            int count;
        };
        std::vector<Seen> seen;
        for (int i = 0; i < n; ++i) {
            std::optional<PreviewSurfaceSample> s =
                bsdf.sample(wo, rng.get1d(), rng.get2d(), TransportMode::Radiance);
            if (!s || !s->is_delta) continue;
            auto it = std::find_if(seen.begin(), seen.end(), [&](const Seen& x) { return x.wi == s->wi; });
            if (it == seen.end()) {
                seen.push_back({s->wi, s->pdf, 1});
            } else {
                ASSERT_EQ(it->pdf, s->pdf) << "one Dirac direction, two different pdfs";
                ++it->count;
            }
        }
        ASSERT_LE(seen.size(), 2u) << "at most a mirror and a refraction direction";
        for (const Seen& x : seen) {
            double freq = double(x.count) / n;
            double sd = std::sqrt(x.pdf * (1.0 - x.pdf) / n) + 1e-6;
            EXPECT_NEAR(freq, x.pdf, 5 * sd) << GetParam().name << " wo " << str(wo) << " wi " << str(x.wi);
        }
    }
}

std::string config_name(const ::testing::TestParamInfo<NamedParams>& info) {
    std::string n = info.param.name;
    for (char& ch : n)
        if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
    return n;
}

INSTANTIATE_TEST_SUITE_P(All, PreviewSurfaceConfig, ::testing::ValuesIn(all_configurations()), config_name);
INSTANTIATE_TEST_SUITE_P(Dirac, PreviewSurfaceDiracConfig, ::testing::ValuesIn(dirac_configurations()), config_name);

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
