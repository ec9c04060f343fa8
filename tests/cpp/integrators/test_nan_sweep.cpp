// NaN / Inf sweep (DESIGN.md section 5: no NaN or Inf ever reaches the film). One scene
// holds the UsdPreviewSurface corner cases -- roughness 0 and 1 x ior 1.0 and 1.0005 (both
// pass-through) x opacity 0, 0.5 and 1, plus ior 1.002 (just past the pass-through
// threshold), 0.2 and 5 (the clamps), roughness at the Dirac threshold, white mirror,
// clearcoat over glass, specular workflow with F0 = 1 -- on smooth-shaded balls (shading
// normals != geometric normals), cut-outs (textured alpha, constant opacity below and
// above the threshold), an extreme normal map, degenerate and emissive triangles, and
// zero-size lights of every kind next to a tiny bright sphere, a delta sun, a dome and a
// zero-angle cone. Seen from an overview camera, a camera grazing the floor, one in the
// plane of a wall and one almost touching a ball: PT, BDPT, PSSMLT and CMLT renders have
// no non-finite or negative pixel or variance and nan_samples == 0.
#include "test_util.h"

#include "integrators/common/render.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

using namespace cmlt;
using namespace cmlt::test;

namespace {

/// UV sphere with smooth vertex normals (outward winding).
MeshData ball_mesh(float r, uint32_t material, int nt = 10, int np = 20) {
    std::vector<Vec3> p, n;
    std::vector<uint32_t> idx;
    for (int i = 0; i <= nt; ++i)
        for (int j = 0; j <= np; ++j) {
            float th = k_pi * float(i) / float(nt), ph = 2.f * k_pi * float(j) / float(np);
            Vec3 d(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
            p.push_back(d * r);
            n.push_back(d);
        }
    auto at = [&](int i, int j) { return uint32_t(i * (np + 1) + j); };
    for (int i = 0; i < nt; ++i)
        for (int j = 0; j < np; ++j) {
            if (i > 0) idx.insert(idx.end(), {at(i, j), at(i, j + 1), at(i + 1, j)});
            if (i + 1 < nt) idx.insert(idx.end(), {at(i, j + 1), at(i + 1, j + 1), at(i + 1, j)});
        }
    return make_mesh_data(p, idx, std::vector<uint32_t>(idx.size() / 3, material), n);
}

/// Quad with uvs 0..1 (for textures: cut-outs, normal maps).
MeshData uv_quad(const Vec3& c, const Vec3& u, const Vec3& v, uint32_t material) {
    struct Owned {
        std::vector<float> p, uv;
        std::vector<uint32_t> idx, mat;
    };
    auto o = std::make_shared<Owned>();
    for (const Vec3& q : {c - u - v, c + u - v, c + u + v, c - u + v}) o->p.insert(o->p.end(), {q.x, q.y, q.z});
    o->p.insert(o->p.end(), {0.f, 0.f, 0.f});
    o->uv = {0, 0, 1, 0, 1, 1, 0, 1};
    o->idx = {0, 1, 2, 0, 2, 3};
    o->mat = {material, material};
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

TextureDesc texture(int w, int h, int ch, std::vector<float> texels, Vec4 scale = Vec4(1.f, 1.f, 1.f, 1.f),
                    Vec4 bias = Vec4(0.f, 0.f, 0.f, 0.f)) {
    auto img = std::make_shared<std::vector<float>>(std::move(texels));
    TextureDesc d;
    d.data = img->data();
    d.width = w;
    d.height = h;
    d.channels = ch;
    d.scale = scale;
    d.bias = bias;
    d.owner = img;
    return d;
}

Material preview(float roughness, float ior, float opacity) {
    Material m;
    m.preview = true;
    m.diffuse = Spectrum(0.7f, 0.6f, 0.5f);
    m.roughness = roughness;
    m.ior = ior;
    m.opacity = opacity;
    return m;
}

enum class View { overview, grazing_floor, in_wall_plane, touching_ball };

void sweep_scene(Scene& s, View view) {
    std::vector<Material> mats;
    mats.push_back(Material{Spectrum(0.6f), Spectrum(0.f)});  // 0: floor
    // The grid of the brief: roughness {0, 1} x ior {1.0, 1.0005} x opacity {0, 0.5, 1}.
    for (float r : {0.f, 1.f})
        for (float ior : {1.f, 1.0005f})
            for (float op : {0.f, 0.5f, 1.f}) mats.push_back(preview(r, ior, op));
    // Neighbours of the thresholds and the clamps.
    for (float ior : {1.002f, 0.2f, 5.f})
        for (float r : {0.f, 1.f}) mats.push_back(preview(r, ior, 0.f));
    mats.push_back(preview(0.0316f, 1.5f, 0.f));  // alpha ~ 1e-3: the Dirac threshold
    mats.push_back(preview(0.001f, 1.5f, 0.5f));
    {
        Material m = preview(0.f, 1.5f, 1.f);  // white mirror
        m.diffuse = Spectrum(1.f);
        m.metallic = 1.f;
        mats.push_back(m);
        m.roughness = 1.f;
        mats.push_back(m);
    }
    {
        Material m = preview(0.f, 1.5f, 0.f);  // smooth clearcoat over smooth glass
        m.clearcoat = 1.f;
        m.clearcoat_roughness = 0.f;
        mats.push_back(m);
    }
    {
        Material m = preview(0.f, 1.5f, 1.f);  // specular workflow, F0 = 1
        m.use_specular_workflow = true;
        m.specular = Spectrum(1.f);
        mats.push_back(m);
    }
    const uint32_t n_balls = uint32_t(mats.size()) - 1;
    // Cut-outs and maps (textures 0: alpha checker, 1: extreme normal map).
    s.add_texture(texture(2, 2, 4, {1, 1, 1, 0, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0}), "alpha");
    s.add_texture(texture(1, 1, 3, {0.9995f, 0.5f, 0.505f}, Vec4(2.f, 2.f, 2.f, 1.f), Vec4(-1.f, -1.f, -1.f, 0.f)),
                  "normal");
    const uint32_t m_cut_tex = uint32_t(mats.size());
    {
        Material m = preview(0.5f, 1.5f, 1.f);
        m.tex_opacity = 0;
        m.opacity_threshold = 0.5f;
        mats.push_back(m);
    }
    {
        Material m = preview(0.5f, 1.5f, 0.3f);  // below the threshold: no surface
        m.opacity_threshold = 0.5f;
        mats.push_back(m);
        m.opacity = 0.7f;  // above: opaque
        mats.push_back(m);
    }
    const uint32_t m_normal = uint32_t(mats.size());
    {
        Material m = preview(0.2f, 1.5f, 1.f);
        m.tex_normal = 1;
        mats.push_back(m);
        Material lam{Spectrum(0.5f), Spectrum(0.f)};
        lam.tex_normal = 1;
        mats.push_back(lam);
    }
    const uint32_t m_emit = uint32_t(mats.size());
    mats.push_back(Material{Spectrum(0.2f), Spectrum(4.f, 3.f, 2.f)});
    s.set_materials(mats);

    s.add_instance(s.add_mesh("/floor", quad_mesh(Vec3(0.f), Vec3(6, 0, 0), Vec3(0, 0, -6))), Mat4());
    for (uint32_t k = 0; k < n_balls; ++k) {
        float x = -2.4f + 0.6f * float(k % 9), z = -0.6f * float(k / 9);
        s.add_instance(s.add_mesh("/ball" + std::to_string(k), ball_mesh(0.25f, k + 1)),
                       Mat4::translate(x, 0.26, z));
    }
    // A wall of cut-outs and normal maps behind the balls (normal +z toward the camera).
    for (uint32_t k = 0; k < 5; ++k)
        s.add_instance(s.add_mesh("/card" + std::to_string(k),
                                  uv_quad(Vec3(-2.f + 1.f * float(k), 0.8f, -2.5f), Vec3(0.45f, 0, 0),
                                          Vec3(0, 0.5f, 0), k < 3 ? m_cut_tex + k : m_normal + (k - 3))),
                       Mat4());
    // Emissive triangles: a degenerate one and a thin sliver.
    s.add_instance(s.add_mesh("/emit", make_mesh_data({Vec3(0, 1, 0), Vec3(1, 1, 0), Vec3(2, 1, 0),
                                                       Vec3(-1, 1.5f, 0.5f), Vec3(1, 1.5f, 0.5f), Vec3(0, 1.5f + 1e-6f, 0.5f)},
                                                      {0, 1, 2, 3, 4, 5}, {m_emit, m_emit})),
                   Mat4());

    // Lights: zero-size ones of every kind, a tiny bright sphere, a regular rect, a delta
    // sun, a dome, a disk with a zero-angle cone and a huge focus.
    auto light = [&](LightDesc::Kind k, const Mat4& xf, float w, float h, float r, float len) {
        LightDesc d;
        d.kind = k;
        d.transform = xf;
        d.width = w;
        d.height = h;
        d.radius = r;
        d.length = len;
        d.radiance = Spectrum(5.f);
        s.add_light(d);
    };
    Mat4 up = Mat4::translate(0, 2, 0) * Mat4::rotate(90, 1, 0, 0);
    light(LightDesc::Kind::rect, up, 0.f, 1.f, 0.f, 0.f);
    light(LightDesc::Kind::rect, up, 1.f, 0.f, 0.f, 0.f);
    light(LightDesc::Kind::disk, up, 0.f, 0.f, 0.f, 0.f);
    light(LightDesc::Kind::sphere, Mat4::translate(0, 1, 1), 0.f, 0.f, 0.f, 0.f);
    light(LightDesc::Kind::cylinder, Mat4::translate(0, 1, 1), 0.f, 0.f, 0.f, 1.f);
    light(LightDesc::Kind::cylinder, Mat4::translate(0, 1, 1), 0.f, 0.f, 0.2f, 0.f);
    light(LightDesc::Kind::rect, Mat4::translate(0.5, 2.5, -0.5) * Mat4::rotate(90, 1, 0, 0), 0.4f, 0.4f, 0.f, 0.f);
    {
        LightDesc tiny;  // tiny and very bright
        tiny.kind = LightDesc::Kind::sphere;
        tiny.transform = Mat4::translate(-1, 1.2, 0.3);
        tiny.radius = 1e-4f;
        tiny.radiance = Spectrum(1e7f);
        s.add_light(tiny);
        tiny.treat_as_point = true;
        tiny.radius = 0.f;
        s.add_light(tiny);
        LightDesc sun;
        sun.kind = LightDesc::Kind::distant;
        sun.angle = 0.f;
        sun.radiance = Spectrum(2.f);
        sun.transform = Mat4::rotate(-70, 1, 0.2, 0);
        s.add_light(sun);
        LightDesc dome;
        dome.kind = LightDesc::Kind::dome;
        dome.radiance = Spectrum(0.3f, 0.4f, 0.5f);
        s.add_light(dome);
        LightDesc cone;
        cone.kind = LightDesc::Kind::disk;
        cone.transform = Mat4::translate(1, 2, 0) * Mat4::rotate(90, 1, 0, 0);
        cone.radius = 0.2f;
        cone.radiance = Spectrum(20.f);
        cone.cone_angle = 0.f;
        cone.cone_softness = 1.f;
        cone.focus = 1e4f;
        s.add_light(cone);
    }

    switch (view) {
        case View::overview:
            s.set_camera(camera_at(Mat4::translate(0, 2, 4) * Mat4::rotate(-25, 1, 0, 0), 20.f, 36.f));
            break;
        case View::grazing_floor:  // 0.1 mm above the floor, looking along it
            s.set_camera(camera_at(Mat4::translate(0.05, 1e-4, 4), 35.f, 36.f));
            break;
        case View::in_wall_plane:  // in the plane of the cards (z = -2.5), looking along it
            s.set_camera(camera_at(Mat4::translate(3.5, 0.8, -2.5) * Mat4::rotate(90, 0, 1, 0), 25.f, 36.f));
            break;
        case View::touching_ball:  // 1e-5 from the first ball's surface, looking at it
            s.set_camera(camera_at(Mat4::translate(-2.4, 0.26, 0.25f + 1e-5f), 18.f, 36.f));
            break;
    }
    s.commit();
}

}  // namespace

TEST(NanSweep, NoNonFinitePixelAnywhere) {
    const View views[] = {View::overview, View::grazing_floor, View::in_wall_plane, View::touching_ball};
    const char* names[] = {"overview", "grazing floor", "in wall plane", "touching ball"};
    for (int v = 0; v < 4; ++v) {
        Scene s;
        sweep_scene(s, views[v]);
        for (const char* integrator : {"pt", "bdpt", "pssmlt", "cmlt"}) {
            RenderSettings st;
            st.width = 24;
            st.height = 16;
            st.spp = 64;
            st.max_depth = 12;
            st.threads = 2;
            st.seed = 5;
            st.integrator = integrator;
            st.chains = 64;
            st.bootstrap_samples = 2048;
            RenderResult r = render(s, st);
            std::string what = std::string(integrator) + ", " + names[v];
            EXPECT_EQ(r.stats.nan_samples, 0u)
                << what << ": first at pixel (" << r.stats.first_nan_x << ", " << r.stats.first_nan_y
                << ") sample " << r.stats.first_nan_sample;
            size_t bad = 0, negative = 0;
            double sum = 0;
            for (float x : r.image) {
                bad += !std::isfinite(x);
                negative += x < 0.f;
                sum += x;
            }
            for (float x : r.variance) bad += !std::isfinite(x) || x < 0.f;
            EXPECT_EQ(bad, 0u) << what;
            EXPECT_EQ(negative, 0u) << what;
            EXPECT_GT(sum, 0.0) << what << ": black image (nothing rendered?)";
            std::printf("[nan sweep %s] mean %.4g, rays %llu, nan_samples %llu\n", what.c_str(),
                        sum / double(r.image.size()), (unsigned long long)r.stats.rays,
                        (unsigned long long)r.stats.nan_samples);
        }
    }
}
