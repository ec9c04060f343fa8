/// \file PreviewSurfaceBsdf: construction, and per configuration sample/eval/pdf
/// consistency, reciprocity, the white furnace and the Dirac pdfs. The lossless furnaces,
/// the Dirac lobes and the NaN/Inf sweep are in test_preview_surface_lobes.cpp, the chi^2
/// tests in test_preview_surface_chi2.cpp.
#include "bsdf_test_util.h"
#include "preview_surface_checks.h"
#include "materials/bsdf.h"
#include "materials/fresnel.h"
#include "materials/preview_surface.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>

namespace cmlt::test {
namespace {

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

TEST_P(PreviewSurfaceConfig, test04b_eval_pdf_and_pdf_pair_are_eval_and_pdf_bit_for_bit) {
    // eval_pdf computes what eval and pdf compute, and pdf_pair what pdf computes both
    // ways, sharing their common terms: the same floats, for reflection and transmission
    // pairs, both transport modes, and through the Bsdf wrapper with a shading normal away
    // from the geometric one
    const PreviewSurfaceBsdf bsdf(GetParam().params);
    const Bsdf wrapped(bsdf, normalize(Vec3(0.3f, -0.2f, 1.f)), Vec3(0.f, 0.f, 1.f));
    TestRng rng(29, 4);
    int nonzero = 0;
    for (int i = 0; i < 4000; ++i) {
        const Vec3 wo = i < 100 ? test_outgoing_directions()[size_t(i) % 10] : rng.uniform_sphere();
        const Vec3 wi = rng.uniform_sphere();
        for (TransportMode mode : {TransportMode::Radiance, TransportMode::Importance}) {
            float pdf = -1.f;
            const Spectrum f = bsdf.eval_pdf(wo, wi, mode, &pdf);
            const Spectrum f0 = bsdf.eval(wo, wi, mode);
            const float pdf0 = bsdf.pdf(wo, wi);
            ASSERT_EQ(f.x, f0.x) << "wo " << str(wo) << " wi " << str(wi);
            ASSERT_EQ(f.y, f0.y);
            ASSERT_EQ(f.z, f0.z);
            ASSERT_EQ(pdf, pdf0) << "wo " << str(wo) << " wi " << str(wi);
            nonzero += pdf > 0.f;
            float wpdf = -1.f;
            const Spectrum wf = wrapped.eval_pdf(wo, wi, mode, &wpdf);
            const Spectrum wf0 = wrapped.eval(wo, wi, mode);
            ASSERT_EQ(wf.x, wf0.x);
            ASSERT_EQ(wf.y, wf0.y);
            ASSERT_EQ(wf.z, wf0.z);
            ASSERT_EQ(wpdf, wrapped.pdf(wo, wi));
        }
        // pdf_pair: both directions' densities, bit for bit
        float fwd = -1.f, rev = -1.f;
        bsdf.pdf_pair(wo, wi, &fwd, &rev);
        ASSERT_EQ(fwd, bsdf.pdf(wo, wi)) << "wo " << str(wo) << " wi " << str(wi);
        ASSERT_EQ(rev, bsdf.pdf(wi, wo)) << "wo " << str(wo) << " wi " << str(wi);
        wrapped.pdf_pair(wo, wi, &fwd, &rev);
        ASSERT_EQ(fwd, wrapped.pdf(wo, wi));
        ASSERT_EQ(rev, wrapped.pdf(wi, wo));
    }
    if (!bsdf.is_pure_delta()) {
        EXPECT_GT(nonzero, 500);
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

}  // namespace
}  // namespace cmlt::test
