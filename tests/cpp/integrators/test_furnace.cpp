// Scene-level furnace tests with UsdPreviewSurface materials, PT and BDPT.
//
// A convex, flat-faced object (a rotated cube: shading normal = geometric normal, so the
// models' own energy balance is what is tested) under uniform illumination Le -- a
// uniform dome, or the inside of a closed cube that emits Le and reflects nothing. Every
// pixel then shows Le times the fraction of the light that leaves the object toward the
// camera after any number of bounces:
//  * lossless models (white Lambert, legacy and UsdPreviewSurface; white mirror; smooth
//    glass; ior 1 and 1.0005 pass-through) give exactly Le everywhere;
//  * lossy models (rough dielectric, rough white metal, white plastic, clearcoat over a
//    white base) give at most Le (microfacet single scattering and the layering
//    approximations lose energy), and PT and BDPT agree on them.
//
// Statistics per channel (standard errors from the variance AOV, image_stats.h), with the
// file's false-alarm rate held at 1e-2 (Bonferroni over 28 lossless renders and 6 lossy
// cases). Lossless: 8x8 blocks within z(2.5e-4 / (blocks x 3)) standard errors of Le, the
// image mean within z(2.5e-5 / 3) standard errors and resolved to 1% (a 2% loss fails):
// 2.75e-4 per render. Lossy: the image mean below Le + z(2.5e-5 / 3) standard errors (PT
// and BDPT), above Le / 4, and the PT / BDPT agreement of image_stats.h at 2.5e-4 (blocks)
// + 2.5e-5 (means): 3e-4 per case. Total 28 x 2.75e-4 + 6 x 3e-4 = 9.5e-3.
// (128 spp: at 32 spp the smooth-glass pixels' variance estimates were too unreliable --
// rare large lobe-selection weights -- and a block showed |z| = 4.3 that 1024 spp and
// another seed did not confirm.)
#include "image_stats.h"
#include "test_util.h"

#include "integrators/common/render.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

using namespace cmlt;
using namespace cmlt::test;

namespace {

const Spectrum k_le(0.8f, 1.f, 1.2f);
constexpr double k_alpha_blocks = 2.5e-4, k_alpha_mean = 2.5e-5;  // per render / case

struct FurnaceMaterial {
    std::string name;
    Material m;
};

Material preview() {
    Material m;
    m.preview = true;
    return m;
}

std::vector<FurnaceMaterial> lossless_materials() {
    std::vector<FurnaceMaterial> out;
    out.push_back({"legacy_lambert_white", Material{Spectrum(1.f), Spectrum(0.f)}});
    {
        Material m = preview();  // specular workflow with F0 = 0: exactly Lambert
        m.use_specular_workflow = true;
        m.specular = Spectrum(0.f);
        m.diffuse = Spectrum(1.f);
        out.push_back({"preview_lambert_white", m});
    }
    {
        Material m = preview();  // F0 = 1: Schlick is 1 at every angle
        m.diffuse = Spectrum(1.f);
        m.metallic = 1.f;
        m.roughness = 0.f;
        out.push_back({"white_mirror", m});
    }
    {
        Material m = preview();
        m.diffuse = Spectrum(0.f);
        m.opacity = 0.f;
        m.ior = 1.5f;
        m.roughness = 0.f;
        out.push_back({"smooth_glass", m});
    }
    {
        Material m = preview();
        m.diffuse = Spectrum(0.f);
        m.opacity = 0.f;
        m.ior = 1.f;
        m.roughness = 0.3f;
        out.push_back({"pass_through_ior1", m});
    }
    {
        Material m = preview();
        m.diffuse = Spectrum(0.f);
        m.opacity = 0.f;
        m.ior = 1.0005f;
        m.roughness = 0.f;
        out.push_back({"pass_through_ior1.0005", m});
    }
    {
        Material m = preview();  // white Lambert half transparent over smooth glass
        m.use_specular_workflow = true;
        m.specular = Spectrum(0.f);
        m.diffuse = Spectrum(1.f);
        m.opacity = 0.5f;
        m.ior = 1.5f;
        m.roughness = 0.f;
        out.push_back({"half_lambert_half_smooth_glass", m});
    }
    return out;
}

std::vector<FurnaceMaterial> lossy_materials() {
    std::vector<FurnaceMaterial> out;
    {
        Material m = preview();
        m.diffuse = Spectrum(0.f);
        m.opacity = 0.f;
        m.ior = 1.5f;
        m.roughness = 0.5f;
        out.push_back({"rough_glass_r0.5", m});
    }
    for (float r : {0.5f, 1.f}) {
        Material m = preview();
        m.diffuse = Spectrum(1.f);
        m.metallic = 1.f;
        m.roughness = r;
        out.push_back({"rough_white_metal_r" + std::to_string(r).substr(0, 3), m});
    }
    {
        Material m = preview();
        m.diffuse = Spectrum(1.f);
        m.roughness = 0.3f;
        out.push_back({"white_plastic_r0.3", m});
    }
    {
        Material m = preview();
        m.use_specular_workflow = true;
        m.specular = Spectrum(0.f);
        m.diffuse = Spectrum(1.f);
        m.clearcoat = 1.f;
        m.clearcoat_roughness = 0.1f;
        out.push_back({"clearcoat_over_white_lambert", m});
    }
    {
        Material m = preview();
        m.diffuse = Spectrum(1.f);
        m.metallic = 1.f;
        m.roughness = 0.f;
        m.clearcoat = 1.f;
        m.clearcoat_roughness = 0.3f;
        out.push_back({"clearcoat_over_white_mirror", m});
    }
    return out;
}

enum class Surround { dome, emitting_box };

/// The object (material 0): a cube of half size 0.5, rotated so that the camera sees
/// three faces; the camera at distance 2.5. Surround: a uniform dome, or a closed cube
/// of half size 3 around everything that emits Le from its inside and is black.
void furnace(Scene& s, const Material& m, Surround sur) {
    Material wall{Spectrum(0.f), k_le};
    s.set_materials({m, wall});
    s.add_instance(s.add_mesh("/object", cube_mesh(0.5f, 0)),
                   Mat4::rotate(35, 1, 0, 0) * Mat4::rotate(40, 0, 1, 0));
    if (sur == Surround::dome) {
        LightDesc dome;
        dome.kind = LightDesc::Kind::dome;
        dome.radiance = k_le;
        s.add_light(dome);
    } else {
        s.add_instance(s.add_mesh("/walls", cube_mesh(3.f, 1)), Mat4());
    }
    s.set_camera(camera_at(Mat4::translate(0.1, -0.05, 2.5), 30.f, 36.f));
    s.commit();
}

RenderResult render_furnace(const Material& m, Surround sur, const char* integrator, int spp,
                            uint64_t seed = 21) {
    Scene s;
    furnace(s, m, sur);
    RenderSettings st;
    st.width = st.height = 24;
    st.spp = spp;
    st.max_depth = 64;
    st.threads = 2;
    st.seed = seed;
    st.integrator = integrator;
    RenderResult r = render(s, st);
    EXPECT_EQ(r.stats.nan_samples, 0u);
    return r;
}

void expect_lossless(const RenderResult& r, const std::string& what) {
    BlockStats b = block_stats(r, 8);
    const double zb = z_for(k_alpha_blocks / double(b.mean.size()));
    double worst = 0;
    for (size_t k = 0; k < b.mean.size(); ++k) {
        double want = k_le[int(k % 3)], se = std::sqrt(b.var[k]);
        double z = std::fabs(b.mean[k] - want) / std::max(se, 1e-300);
        if (std::fabs(b.mean[k] - want) <= 1e-4 * want) z = 0;  // float rounding
        worst = std::max(worst, z);
        EXPECT_LT(z, zb) << what << ": block " << k / 3 << " channel " << k % 3 << " = " << b.mean[k]
                         << ", expected " << want << " (stderr " << se << ")";
    }
    BlockStats m = block_stats(r, 0);
    const double zm = z_for(k_alpha_mean / 3);
    double rel[3];
    for (int c = 0; c < 3; ++c) {
        double want = k_le[c], se = std::sqrt(m.var[size_t(c)]), mean = m.mean[size_t(c)];
        rel[c] = mean / want - 1;
        EXPECT_LT(std::fabs(mean - want), zm * se + 1e-4 * want)
            << what << ": channel " << c << " mean " << mean << " expected " << want << " (stderr " << se << ")";
        EXPECT_LT(zm * se, 0.01 * want) << what << ": channel " << c << " not resolved to 1%";
    }
    std::printf("[furnace %s] mean / Le - 1: %+.5f %+.5f %+.5f, worst block |z| %.2f (limit %.2f)\n",
                what.c_str(), rel[0], rel[1], rel[2], worst, zb);
}

}  // namespace

TEST(Furnace, LosslessUnderUniformDomePt) {
    for (const FurnaceMaterial& fm : lossless_materials())
        expect_lossless(render_furnace(fm.m, Surround::dome, "pt", 128), fm.name + " dome pt");
}

TEST(Furnace, LosslessUnderUniformDomeBdpt) {
    // 512 spp: half_lambert_half_smooth_glass is heavy-tailed in bdpt under the dome; at
    // 128 spp its mean is resolved to 1 % in only ~half the seeds (40 seeds, either
    // random-number layout), at 512 spp in all 40 (worst 0.87 %).
    for (const FurnaceMaterial& fm : lossless_materials())
        expect_lossless(render_furnace(fm.m, Surround::dome, "bdpt", 512), fm.name + " dome bdpt");
}

TEST(Furnace, LosslessInsideEmittingBoxPt) {
    for (const FurnaceMaterial& fm : lossless_materials())
        expect_lossless(render_furnace(fm.m, Surround::emitting_box, "pt", 128), fm.name + " box pt");
}

TEST(Furnace, LosslessInsideEmittingBoxBdpt) {
    // 512 spp, as under the dome: half_lambert_half_smooth_glass's mean is resolved to 1 %
    // at 128 spp in 21 and 23 of 30 seeds (the Sobol scrambles seeded by their hash and by
    // Philox), at 512 spp in 30 of 30 (worst 0.69 %).
    for (const FurnaceMaterial& fm : lossless_materials())
        expect_lossless(render_furnace(fm.m, Surround::emitting_box, "bdpt", 512), fm.name + " box bdpt");
}

TEST(Furnace, LossyAtMostLeAndPtBdptAgree) {
    const double zm = z_for(k_alpha_mean / 3);
    for (const FurnaceMaterial& fm : lossy_materials()) {
        RenderResult pt = render_furnace(fm.m, Surround::dome, "pt", 128);
        RenderResult bd = render_furnace(fm.m, Surround::dome, "bdpt", 64);
        for (const RenderResult* r : {&pt, &bd}) {
            BlockStats m = block_stats(*r, 0);
            for (int c = 0; c < 3; ++c) {
                double want = k_le[c], se = std::sqrt(m.var[size_t(c)]), mean = m.mean[size_t(c)];
                EXPECT_LT(mean, want + zm * se + 1e-4 * want)
                    << fm.name << (r == &pt ? " pt" : " bdpt") << ": channel " << c << " mean " << mean
                    << " above Le " << want << " (stderr " << se << "): creates energy";
                EXPECT_GT(mean, 0.25 * want) << fm.name;
            }
        }
        BlockStats m = block_stats(pt, 0);
        std::printf("[furnace %s] pt image mean / Le: %.4f %.4f %.4f\n", fm.name.c_str(),
                    m.mean[0] / k_le[0], m.mean[1] / k_le[1], m.mean[2] / k_le[2]);
        AgreementOptions o;
        o.require_resolution = false;
        o.alpha_blocks = k_alpha_blocks;
        o.alpha_mean = k_alpha_mean;
        expect_images_agree(pt, bd, fm.name + " pt vs bdpt", o);
    }
}
