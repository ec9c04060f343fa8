// Scene: boundary validation (errors name the mesh), emissive-triangle lights,
// light selection floor, surface interactions, robust ray offsets at any scale.
#include "test_util.h"

#include "math/frame.h"
#include "util/error.h"

#include <gtest/gtest.h>

using namespace cmlt;
using namespace cmlt::test;

namespace {

template <typename F>
std::string error_of(F&& f) {
    try {
        f();
    } catch (const SceneError& e) {
        return e.what();
    }
    return "";
}

}  // namespace

TEST(Scene, ValidationNamesTheMesh) {
    Scene s;
    std::string msg = error_of([&] {
        s.add_mesh("/geo/rock", make_mesh_data({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}, {0, 1, 3}));
    });
    EXPECT_NE(msg.find("/geo/rock"), std::string::npos) << msg;
    EXPECT_NE(msg.find("refers to point 3"), std::string::npos) << msg;
    msg = error_of([&] {
        s.add_mesh("/geo/nan", make_mesh_data({Vec3(0, 0, 0), Vec3(NAN, 0, 0), Vec3(0, 1, 0)}, {0, 1, 2}));
    });
    EXPECT_NE(msg.find("/geo/nan"), std::string::npos) << msg;
    msg = error_of([&] {
        s.add_mesh("/geo/inf", make_mesh_data({Vec3(0, 0, 0), Vec3(0, 0, 0), Vec3(0, 1, 0)}, {0, 1, 2}, {},
                                              {Vec3(0, 0, 1), Vec3(INFINITY, 0, 0), Vec3(0, 0, 1)}));
    });
    EXPECT_NE(msg.find("normals"), std::string::npos) << msg;
    uint32_t m = s.add_mesh("/geo/tri", make_mesh_data({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}, {0, 1, 2}, {4}));
    s.add_instance(m, Mat4());
    msg = error_of([&] { s.commit(); });  // material id 4 but one material
    EXPECT_NE(msg.find("/geo/tri"), std::string::npos) << msg;
    EXPECT_NE(msg.find("material_ids"), std::string::npos) << msg;
    EXPECT_THROW(s.add_instance(7, Mat4()), SceneError);
    EXPECT_THROW(s.add_instance(m, Mat4::scale(0, 0, 0)), SceneError);
    EXPECT_THROW(s.set_materials({}), SceneError);
    LightDesc cyl;  // supported now (lights/cylinder_light.h); negative sizes still refused
    cyl.kind = LightDesc::Kind::cylinder;
    EXPECT_NO_THROW(s.add_light(cyl));
    cyl.radius = -1.f;
    EXPECT_THROW(s.add_light(cyl), SceneError);
    // Point-count change on update.
    std::vector<float> pts(6 * 3, 0.f);
    EXPECT_THROW(s.update_mesh_points(m, pts.data(), 5, nullptr, nullptr), SceneError);
}

TEST(Scene, EmissiveTrianglesBecomeLights) {
    Scene s;
    s.set_materials({Material{Spectrum(0.5f), Spectrum(0.f)}, Material{Spectrum(0.f), Spectrum(4.f)}});
    uint32_t q = s.add_mesh("/light", quad_mesh(Vec3(0, 0, 2), Vec3(1, 0, 0), Vec3(0, 1, 0), 1));
    uint32_t g = s.add_mesh("/ground", quad_mesh(Vec3(0.f), Vec3(5, 0, 0), Vec3(0, 5, 0), 0));
    // A degenerate emissive triangle is not a light.
    uint32_t dg = s.add_mesh("/degenerate", make_mesh_data({Vec3(0, 0, 1), Vec3(1, 0, 1), Vec3(2, 0, 1)}, {0, 1, 2}, {1}));
    s.add_instance(q, Mat4());
    s.add_instance(q, Mat4::translate(3, 0, 0));
    s.add_instance(g, Mat4());
    s.add_instance(dg, Mat4());
    LightDesc dim;
    dim.kind = LightDesc::Kind::rect;
    dim.radiance = Spectrum(0.f);
    s.add_light(dim);
    s.commit();
    ASSERT_EQ(s.light_count(), 5u);  // dim rect + 2 instances x 2 triangles
    EXPECT_GE(s.triangle_light_index(1, 1), 1);
    EXPECT_EQ(s.triangle_light_index(2, 0), -1);
    EXPECT_EQ(s.triangle_light_index(3, 0), -1);
    double sum = 0;
    for (size_t i = 0; i < s.light_count(); ++i) {
        EXPECT_GT(s.light_pmf(i), 0.f) << i;  // the floor
        sum += s.light_pmf(i);
    }
    EXPECT_NEAR(sum, 1.0, 1e-6);
    EXPECT_LT(s.light_pmf(0), 0.01f);
}

TEST(Scene, InteractionNormalsAndInstances) {
    Scene s;
    // Quad facing +Z with shading normals tilted; instance rotated to face +X.
    MeshData d = make_mesh_data({Vec3(-1, -1, 0), Vec3(1, -1, 0), Vec3(1, 1, 0), Vec3(-1, 1, 0)},
                                {0, 1, 2, 0, 2, 3}, {},
                                {Vec3(0, 0, -1), Vec3(0, 0, -1), Vec3(0, 0, -1), Vec3(0, 0, -1)});
    uint32_t m = s.add_mesh("/q", std::move(d));
    s.add_instance(m, Mat4::translate(5, 0, 0) * Mat4::rotate(90, 0, 1, 0));
    s.commit();
    SurfaceInteraction si;
    ASSERT_TRUE(s.intersect_surface(Ray(Vec3(10, 0.2f, 0.3f), Vec3(-1, 0, 0)), &si));
    EXPECT_NEAR(si.p.x, 5.f, 1e-5f);
    EXPECT_NEAR(si.t, 5.f, 1e-5f);
    EXPECT_NEAR(std::fabs(si.ng.x), 1.f, 1e-5f);
    EXPECT_GT(dot(si.ns, si.ng), 0.f);  // shading normal flipped to the geometric side
    EXPECT_EQ(si.instance_id, 0u);
}

TEST(Scene, SpawnedRaysDoNotSelfIntersectAtAnyScale) {
    for (double scale : {1e-6, 1.0, 1e5}) {
        for (double offset : {0.0, 1e3}) {
            Scene s;
            uint32_t m = s.add_mesh("/plane", quad_mesh(Vec3(0.f), Vec3(1, 0, 0), Vec3(0, 1, 0)));
            Mat4 xf = Mat4::translate(offset * scale, -offset * scale, 0.5 * offset * scale) *
                      Mat4::rotate(33, 1, 2, 3) * Mat4::scale(scale, scale, scale);
            s.add_instance(m, xf);
            s.commit();
            int escapes = 0, n = 0;
            for (uint32_t i = 0; i < 400; ++i) {
                Vec2 u = uniform2(200, i);
                Vec3 target = xf.transform_point(Vec3(u.x * 1.8f - 0.9f, u.y * 1.8f - 0.9f, 0.f));
                Vec3 nrm = normalize(Transform(xf, "t").normal.transform_normal(Vec3(0, 0, 1)));
                Vec3 o = target + nrm * float(3 * scale);
                SurfaceInteraction si;
                if (!s.intersect_surface(Ray(o, normalize(target - o)), &si)) continue;
                ++n;
                // Reflect into a grazing direction on the same side.
                Frame f(si.ng);
                Vec3 d = f.to_world(normalize(Vec3(std::cos(6.28f * u.x), std::sin(6.28f * u.x), 0.02f)));
                if (dot(d, si.wo) < 0) d = d - si.ng * (2 * dot(d, si.ng));
                SurfaceInteraction again;
                if (!s.intersect_surface(si.spawn_ray(d), &again)) ++escapes;
                // And a shadow ray back toward the origin side stays unoccluded.
                EXPECT_FALSE(s.occluded(si.spawn_ray_to(o))) << "scale " << scale;
            }
            EXPECT_GT(n, 300);
            EXPECT_EQ(escapes, n) << "scale " << scale << " offset " << offset;
        }
    }
}
