// Normal maps (make_bsdf, materials/material_eval.cpp): a constant tangent-space normal
// map that tilts the shading normal by theta must shade a flat quad exactly like the quad
// tilted by theta, under a delta distant light:
//  1. orthographic camera (one outgoing direction for the whole image), PT with
//     max_depth 1 (next-event estimation only, so every pixel is deterministic), Lambert
//     and a glossy UsdPreviewSurface, tilts of 35 and 70 degrees: the normal-mapped flat
//     quad, the tilted quad and the BSDF evaluated here in the tilted frame agree pixel for
//     pixel (float rounding), and differ from the un-mapped flat quad;
//  2. the tangent follows dp/du: with u mirrored the normal tilts the other way;
//  3. BDPT with a perspective camera (light-tracing splats go through the adjoint BSDF's
//     shading-normal correction): per-channel image mean = the analytic Lambert value,
//     and so is light tracing alone ((s, t) = (2, 1) unweighted); |z| < z(1e-4 / 3) per
//     channel and estimator (false-alarm rate 2e-4 for the test), resolved to 1% / 2%.
#include "image_stats.h"
#include "test_util.h"

#include "integrators/bdpt/bdpt_tracer.h"
#include "integrators/common/render.h"
#include "materials/bsdf.h"
#include "math/frame.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace cmlt;
using namespace cmlt::test;

namespace {

const Vec3 k_light_dir = normalize(Vec3(0.5f, 0.2f, 0.84f));  // toward the light
const Spectrum k_sun(2.f, 1.5f, 1.f);

/// A 2h x 2h quad in the plane z = 0, normal +z, uv along +x / +y (or -x with mirror_u).
MeshData uv_quad(float h, bool mirror_u) {
    struct Owned {
        std::vector<float> p, uv;
        std::vector<uint32_t> idx, mat;
    };
    auto o = std::make_shared<Owned>();
    o->p = {-h, -h, 0, h, -h, 0, h, h, 0, -h, h, 0, 0, 0, 0};  // + padding row
    o->uv = mirror_u ? std::vector<float>{1, 0, 0, 0, 0, 1, 1, 1}
                     : std::vector<float>{0, 0, 1, 0, 1, 1, 0, 1};
    o->idx = {0, 1, 2, 0, 2, 3};
    o->mat = {0, 0};
    MeshData d;
    d.points = o->p.data();
    d.n_points = 4;
    d.indices = o->idx.data();
    d.n_tris = 2;
    d.uvs = o->uv.data();
    d.material_ids = o->mat.data();
    d.owner = o;
    return d;
}

/// One texel, raw: n = (sin theta, 0, cos theta) stored as n / 2 + 1/2 with UsdUVTexture's
/// scale 2 and bias -1 (the usual normal-map encoding).
TextureDesc normal_texture(float theta_deg) {
    float t = radians(theta_deg);
    auto img = std::make_shared<std::vector<float>>(
        std::vector<float>{0.5f + 0.5f * std::sin(t), 0.5f, 0.5f + 0.5f * std::cos(t)});
    TextureDesc d;
    d.data = img->data();
    d.width = d.height = 1;
    d.channels = 3;
    d.scale = Vec4(2.f, 2.f, 2.f, 1.f);
    d.bias = Vec4(-1.f, -1.f, -1.f, 0.f);
    d.owner = img;
    return d;
}

struct QuadSetup {
    Material material;
    float theta = 35.f;
    enum Kind { flat, mapped, mapped_mirrored, tilted } kind = mapped;
    bool ortho = true;
    float half = 12.f;  ///< half size of the quad
};

void build(Scene& s, const QuadSetup& st) {
    Material m = st.material;
    if (st.kind == QuadSetup::mapped || st.kind == QuadSetup::mapped_mirrored) {
        m.tex_normal = int32_t(s.add_texture(normal_texture(st.theta), "normal"));
    }
    s.set_materials({m});
    uint32_t q = s.add_mesh("/quad", uv_quad(st.half, st.kind == QuadSetup::mapped_mirrored));
    s.add_instance(q, st.kind == QuadSetup::tilted ? Mat4::rotate(st.theta, 0, 1, 0) : Mat4());
    LightDesc sun;
    sun.kind = LightDesc::Kind::distant;
    sun.angle = 0.f;
    sun.radiance = k_sun;
    Frame f(k_light_dir);
    Mat4 xf;  // local +Z -> the light direction
    for (int r = 0; r < 3; ++r) {
        xf.m[r][0] = f.s[r];
        xf.m[r][1] = f.t[r];
        xf.m[r][2] = f.n[r];
    }
    sun.transform = xf;
    s.add_light(sun);
    CameraDesc cam = camera_at(Mat4::translate(0, 0, 3), 36.f, 36.f);
    if (st.ortho) {
        cam.projection = CameraDesc::Projection::orthographic;
        cam.horizontal_aperture = cam.vertical_aperture = 20.f;  // 2 world units
    }
    s.set_camera(cam);
    s.commit();
}

RenderResult render_setup(const QuadSetup& st, const char* integrator, int spp, int w = 16) {
    Scene s;
    build(s, st);
    RenderSettings rs;
    rs.width = rs.height = w;
    rs.spp = spp;
    rs.max_depth = 1;
    rs.threads = 2;
    rs.seed = 3;
    rs.integrator = integrator;
    rs.pixel_filter = "box";  // every sample exact (weight 1): expect_constant's 2e-4
    RenderResult r = render(s, rs);
    EXPECT_EQ(r.stats.nan_samples, 0u);
    return r;
}

Vec3 tilted_normal(float theta_deg, float sign = 1.f) {
    float t = radians(theta_deg);
    return Vec3(sign * std::sin(t), 0.f, std::cos(t));
}

/// Radiance toward +z of a surface with shading normal ns (geometric normal ng) under the
/// sun: f(+z, l) |l . ns| E.
Spectrum expected(const Material& m, const Vec3& ns, const Vec3& ng) {
    Bsdf b = Bsdf::from_material(m, ns, ng);
    return b.eval(Vec3(0, 0, 1), k_light_dir) * std::fabs(dot(k_light_dir, ns)) * k_sun;
}

void expect_constant(const RenderResult& r, const Spectrum& want, const std::string& what) {
    int bad = 0;
    for (size_t i = 0; i < r.image.size(); ++i) {
        float w = want[int(i % 3)];
        if (!(std::fabs(r.image[i] - w) <= 2e-4f * w + 1e-7f)) {
            if (++bad <= 3)
                ADD_FAILURE() << what << ": pixel " << i / 3 << " channel " << i % 3 << " = "
                              << r.image[i] << ", expected " << w;
        }
    }
    EXPECT_EQ(bad, 0) << what;
}

Material lambert() { return Material{Spectrum(0.8f, 0.6f, 0.4f), Spectrum(0.f)}; }
Material glossy() {
    Material m;
    m.preview = true;
    m.diffuse = Spectrum(0.5f, 0.4f, 0.3f);
    m.roughness = 0.4f;
    m.metallic = 0.f;
    return m;
}

}  // namespace

TEST(NormalMap, ConstantTiltShadesLikeTiltedGeometry) {
    for (const Material& m : {lambert(), glossy()})
        for (float theta : {35.f, 70.f}) {
            std::string what = std::string(m.preview ? "glossy" : "lambert") + " tilt " +
                               std::to_string(int(theta));
            QuadSetup st;
            st.material = m;
            st.theta = theta;
            Vec3 ns = tilted_normal(theta);
            Spectrum want = expected(m, ns, Vec3(0, 0, 1));
            Spectrum want_tilted = expected(m, ns, ns);
            EXPECT_NEAR(want.x, want_tilted.x, 1e-5f * want.x) << what;
            Spectrum flat_value = expected(m, Vec3(0, 0, 1), Vec3(0, 0, 1));
            ASSERT_GT(std::fabs(flat_value.x - want.x), 0.05f * want.x) << what << ": not a test";
            st.kind = QuadSetup::mapped;
            expect_constant(render_setup(st, "pt", 2), want, what + " (normal map)");
            st.kind = QuadSetup::tilted;
            expect_constant(render_setup(st, "pt", 2), want, what + " (tilted quad)");
            st.kind = QuadSetup::flat;
            expect_constant(render_setup(st, "pt", 2), flat_value, what + " (flat, no map)");
        }
}

TEST(NormalMap, TangentFollowsDpDu) {
    // u running along -x: the same map tilts the normal toward -x.
    QuadSetup st;
    st.material = lambert();
    st.kind = QuadSetup::mapped_mirrored;
    Spectrum want = expected(st.material, tilted_normal(35.f, -1.f), Vec3(0, 0, 1));
    Spectrum other = expected(st.material, tilted_normal(35.f, 1.f), Vec3(0, 0, 1));
    ASSERT_GT(std::fabs(other.x - want.x), 0.2f * want.x);
    expect_constant(render_setup(st, "pt", 2), want, "mirrored u");
}

TEST(NormalMap, BdptLightTracingSeesTheShadingNormal) {
    // Perspective camera: BDPT's (s, t) = (2, 1) light-tracing splats carry the adjoint
    // shading-normal correction |wo.ns| |wi.ng| / (|wo.ng| |wi.ns|); with MIS against
    // next-event estimation the image must still be the Lambert value for the tilted normal.
    QuadSetup st;
    st.material = lambert();
    st.theta = 50.f;
    st.kind = QuadSetup::mapped;
    st.ortho = false;
    st.half = 1.6f;  // just fills the view: the light's disk (the scene bound) is small
    Spectrum want = expected(st.material, tilted_normal(50.f), Vec3(0, 0, 1));
    RenderResult r = render_setup(st, "bdpt", 256, 24);
    EXPECT_GT(r.stats.splats, 0u);
    BlockStats m = block_stats(r, 0);
    const double z = z_for(1e-4 / 3);
    for (int c = 0; c < 3; ++c) {
        double se = std::sqrt(m.var[size_t(c)]), mean = m.mean[size_t(c)];
        EXPECT_LT(std::fabs(mean - want[c]), z * se + 1e-5 * want[c])
            << "channel " << c << ": " << mean << " expected " << want[c] << " stderr " << se;
        EXPECT_LT(z * se, 0.01 * want[c]) << "channel " << c << ": not resolved to 1%";
        std::printf("[bdpt normal map] channel %d: %.6f expected %.6f (stderr %.3g)\n", c, mean,
                    double(want[c]), se);
    }
    // With MIS the splats carry little weight here (the light's disk covers the whole
    // scene bound): light tracing alone, (s, t) = (2, 1) unweighted, must give the same
    // image mean (E[L] = the mean pixel value; every pixel sees the quad).
    Scene s;
    build(s, st);
    const int W = 24;
    Camera cam(s.camera_desc(), W, W);
    BdptTracer tr(s, cam, W, W, 1);
    BdptWorkspace ws;
    BdptCounters c;
    const uint32_t N = 400000;
    double sum[3] = {0, 0, 0}, sum2[3] = {0, 0, 0};
    for (uint32_t i = 0; i < N; ++i) {
        PixelStreamSampler sampler(17, i, 0);
        Vec2 pr;
        Spectrum L = tr.evaluate_strategy_unweighted(1, 2, 1, sampler, ws, &pr, c);
        for (int k = 0; k < 3; ++k) {
            sum[k] += L[k];
            sum2[k] += double(L[k]) * L[k];
        }
    }
    for (int k = 0; k < 3; ++k) {
        double mean = sum[k] / N, se = std::sqrt(std::max(0.0, sum2[k] / N - mean * mean) / (N - 1));
        EXPECT_LT(std::fabs(mean - want[k]), z * se + 1e-5 * want[k])
            << "light tracing, channel " << k << ": " << mean << " expected " << want[k] << " stderr " << se;
        EXPECT_LT(z * se, 0.02 * want[k]) << "light tracing, channel " << k << ": not resolved to 2%";
        std::printf("[light tracing normal map] channel %d: %.5f expected %.5f (stderr %.3g)\n", k,
                    mean, double(want[k]), se);
    }
}
