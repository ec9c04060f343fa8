// Material inputs read from per-vertex primvars (UsdPrimvarReader_*; MeshData::primvars,
// Material::pv_*, materials/material_eval.cpp):
//  1. a hit interpolates the mesh's primvar columns with its barycentrics (a linear function
//     of the position comes back exactly, up to float rounding);
//  2. diffuseColor / opacity / roughness read their columns; a mesh without the columns
//     keeps the constant (the reader's fallback); a texture wins over a primvar;
//  3. a primvar opacity makes the material a possible pass-through (shadow rays step
//     through it); bad column layouts are rejected naming the mesh or material.
#include "test_util.h"

#include "materials/material_eval.h"
#include "util/error.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

using namespace cmlt;
using namespace cmlt::test;

namespace {

/// Linear function per column of the position (x, y) on the plane z = 0.
float column_value(int c, float x, float y) {
    return 0.1f * float(c + 1) + 0.2f * x - 0.15f * float(c % 3) * y + 0.05f * float(c);
}

/// The quad [-1, 1]^2 at z = 0 (normal +z) with `cols` primvar columns of column_value.
MeshData primvar_quad(uint32_t cols) {
    struct Owned {
        std::vector<float> p, pv;
        std::vector<uint32_t> idx;
    };
    auto o = std::make_shared<Owned>();
    const float xy[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (auto& v : xy) {
        o->p.insert(o->p.end(), {v[0], v[1], 0.f});
        for (uint32_t c = 0; c < cols; ++c) o->pv.push_back(column_value(int(c), v[0], v[1]));
    }
    o->p.insert(o->p.end(), {0.f, 0.f, 0.f});  // padding row
    o->idx = {0, 1, 2, 0, 2, 3};
    MeshData d;
    d.points = o->p.data();
    d.n_points = 4;
    d.indices = o->idx.data();
    d.n_tris = 2;
    d.primvars = cols ? o->pv.data() : nullptr;
    d.n_primvar_columns = cols;
    d.owner = o;
    return d;
}

Material primvar_material() {
    Material m;
    m.preview = true;
    m.diffuse = Spectrum(0.5f, 0.5f, 0.5f);  // the reader's fallback
    m.opacity = 1.f;
    m.roughness = 0.5f;
    m.pv_diffuse = 0;    // columns 0..2
    m.pv_opacity = 3;    // column 3
    m.pv_roughness = 4;  // column 4
    return m;
}

SurfaceInteraction hit_at(const Scene& s, float x, float y) {
    SurfaceInteraction si;
    EXPECT_TRUE(s.intersect_surface(Ray(Vec3(x, y, 5.f), Vec3(0, 0, -1)), &si)) << x << "," << y;
    return si;
}

}  // namespace

TEST(PrimvarInputs, HitInterpolatesTheColumns) {
    Scene s;
    s.add_instance(s.add_mesh("/quad", primvar_quad(5)), Mat4());
    s.commit();
    const float pts[][2] = {{0.1f, 0.2f}, {-0.7f, 0.6f}, {0.9f, -0.8f}, {0.f, 0.f}, {-0.3f, -0.9f}};
    for (auto& p : pts) {
        SurfaceInteraction si = hit_at(s, p[0], p[1]);
        ASSERT_EQ(si.n_primvars, 5);
        for (int c = 0; c < 5; ++c)
            EXPECT_NEAR(si.primvars[c], column_value(c, p[0], p[1]), 2e-6f) << "column " << c;
    }
}

TEST(PrimvarInputs, MaterialReadsItsColumnsElseTheConstant) {
    Scene s;
    s.add_instance(s.add_mesh("/with", primvar_quad(5)), Mat4());
    // a second quad without primvars, far to the side
    s.add_instance(s.add_mesh("/without", primvar_quad(0)), Mat4::translate(10, 0, 0));
    s.set_materials({primvar_material()});
    s.commit();
    const float x = 0.3f, y = -0.4f;
    SurfaceInteraction si = hit_at(s, x, y);
    PreviewSurfaceParams p = preview_params(s.material(0), si.uv, s.textures(), si.primvars,
                                            si.n_primvars);
    EXPECT_NEAR(p.diffuse.x, column_value(0, x, y), 2e-6f);
    EXPECT_NEAR(p.diffuse.y, column_value(1, x, y), 2e-6f);
    EXPECT_NEAR(p.diffuse.z, column_value(2, x, y), 2e-6f);
    EXPECT_NEAR(p.opacity, column_value(3, x, y), 2e-6f);
    EXPECT_NEAR(p.roughness, column_value(4, x, y), 2e-6f);
    EXPECT_NEAR(diffuse_colour(s.material(0), si.uv, s.textures(), si.primvars, si.n_primvars).y,
                column_value(1, x, y), 2e-6f);
    // no columns on the mesh: the constants
    SurfaceInteraction bare = hit_at(s, 10.f + x, y);
    EXPECT_EQ(bare.n_primvars, 0);
    PreviewSurfaceParams q = preview_params(s.material(0), bare.uv, s.textures(), bare.primvars,
                                            bare.n_primvars);
    EXPECT_EQ(q.diffuse.x, 0.5f);
    EXPECT_EQ(q.opacity, 1.f);
    EXPECT_EQ(q.roughness, 0.5f);
    // the old signature (no primvars) is the constant too
    EXPECT_EQ(preview_params(s.material(0), si.uv, s.textures()).diffuse.z, 0.5f);
}

TEST(PrimvarInputs, TextureWinsOverPrimvar) {
    Scene s;
    s.add_instance(s.add_mesh("/quad", primvar_quad(5)), Mat4());
    auto img = std::make_shared<std::vector<float>>(std::vector<float>{0.9f, 0.05f, 0.25f});
    TextureDesc d;
    d.data = img->data();
    d.width = d.height = 1;
    d.channels = 3;
    d.owner = img;
    Material m = primvar_material();
    m.tex_diffuse = int32_t(s.add_texture(d, "one texel"));
    s.set_materials({m});
    s.commit();
    SurfaceInteraction si = hit_at(s, 0.2f, 0.2f);
    PreviewSurfaceParams p = preview_params(s.material(0), si.uv, s.textures(), si.primvars,
                                            si.n_primvars);
    EXPECT_NEAR(p.diffuse.x, 0.9f, 1e-6f);
    EXPECT_NEAR(p.diffuse.z, 0.25f, 1e-6f);
}

TEST(PrimvarInputs, PrimvarOpacityPassesShadowRays) {
    Material m = primvar_material();
    m.ior = 1.f;  // an ior-1 interface: (1 - opacity) is a pass-through
    EXPECT_TRUE(may_pass_rays(m));
    m.pv_opacity = -1;
    EXPECT_FALSE(may_pass_rays(m));
    m.opacity_threshold = 0.5f;  // cut-out driven by a primvar
    m.pv_opacity = 3;
    EXPECT_TRUE(may_pass_rays(m));

    // a shadow ray through the quad with opacity 0.25 everywhere: transmittance 0.75
    struct Owned {
        std::vector<float> p, pv;
        std::vector<uint32_t> idx;
    };
    auto o = std::make_shared<Owned>();
    o->p = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0, 0, 0, 0};
    o->pv = {0.25f, 0.25f, 0.25f, 0.25f};
    o->idx = {0, 1, 2, 0, 2, 3};
    MeshData d;
    d.points = o->p.data();
    d.n_points = 4;
    d.indices = o->idx.data();
    d.n_tris = 2;
    d.primvars = o->pv.data();
    d.n_primvar_columns = 1;
    d.owner = o;
    Scene s;
    s.add_instance(s.add_mesh("/veil", std::move(d)), Mat4());
    Material veil;
    veil.preview = true;
    veil.ior = 1.f;
    veil.pv_opacity = 0;
    s.set_materials({veil});
    s.commit();
    ASSERT_TRUE(s.has_pass_through());
    float pass_pdf = 0.f;
    float tr = s.transmittance(Ray(Vec3(0.1f, 0.1f, 2.f), Vec3(0, 0, -4.f), 0.f, 1.f), &pass_pdf);
    EXPECT_NEAR(tr, 0.75f, 1e-5f);
}

TEST(PrimvarInputs, BadLayoutsAreRejected) {
    {
        Scene s;
        EXPECT_THROW(s.add_mesh("/nine", primvar_quad(9)), SceneError);
    }
    {
        MeshData d = primvar_quad(2);
        float* pv = const_cast<float*>(d.primvars);
        pv[3] = std::nanf("");
        Scene s;
        try {
            s.add_mesh("/nan", std::move(d));
            FAIL() << "a NaN primvar was accepted";
        } catch (const SceneError& e) {
            EXPECT_NE(std::string(e.what()).find("/nan"), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find("primvars"), std::string::npos) << e.what();
        }
    }
    {
        Scene s;
        s.add_instance(s.add_mesh("/quad", primvar_quad(5)), Mat4());
        Material m = primvar_material();
        m.pv_diffuse = 6;  // columns 6..8: past the last one
        s.set_materials({m});
        EXPECT_THROW(s.commit(), SceneError);
    }
}
