// Embree queries: known distances, instance transforms, misses, updates, and packet
// queries (4/8/16 with valid masks) agreeing with scalar queries.
#include "test_util.h"

#include "accel/accel.h"
#include "sampling/warp.h"

#include <gtest/gtest.h>

using namespace cmlt;
using namespace cmlt::test;

namespace {

struct AccelFixture : ::testing::Test {
    // Unit quad in z = 0, x, y in [-1, 1].
    std::vector<float> pts = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0, 0, 0, 0 /*pad*/};
    std::vector<uint32_t> idx = {0, 1, 2, 0, 2, 3};
    Accel accel;
    uint32_t mesh = accel.add_mesh(pts.data(), 4, idx.data(), 2);
};

}  // namespace

TEST_F(AccelFixture, KnownDistanceAndMiss) {
    accel.add_instance(mesh, Mat4());
    accel.commit();
    Hit h = accel.intersect(Ray(Vec3(0.25f, 0.5f, 5.f), Vec3(0, 0, -1)));
    ASSERT_TRUE(h.valid());
    EXPECT_NEAR(h.t, 5.f, 1e-5f);
    EXPECT_EQ(h.instance_id, 0u);
    EXPECT_FALSE(accel.intersect(Ray(Vec3(2.f, 0.f, 5.f), Vec3(0, 0, -1))).valid());
    EXPECT_FALSE(accel.intersect(Ray(Vec3(0.f, 0.f, 5.f), Vec3(0, 0, 1))).valid());
    // tfar shorter than the hit: no hit; occluded agrees.
    EXPECT_FALSE(accel.intersect(Ray(Vec3(0.f, 0.f, 5.f), Vec3(0, 0, -1), 0.f, 4.f)).valid());
    EXPECT_TRUE(accel.occluded(Ray(Vec3(0.f, 0.f, 5.f), Vec3(0, 0, -1))));
    EXPECT_FALSE(accel.occluded(Ray(Vec3(0.f, 0.f, 5.f), Vec3(0, 0, -1), 0.f, 4.f)));
}

TEST_F(AccelFixture, InstanceTransformsAreApplied) {
    accel.add_instance(mesh, Mat4::translate(0, 0, 2));
    accel.add_instance(mesh, Mat4::translate(10, 0, 0) * Mat4::scale(3, 3, 3));
    accel.commit();
    Hit h = accel.intersect(Ray(Vec3(0.f, 0.f, 5.f), Vec3(0, 0, -1)));
    ASSERT_TRUE(h.valid());
    EXPECT_NEAR(h.t, 3.f, 1e-5f);
    EXPECT_EQ(h.instance_id, 0u);
    // The scaled copy covers x in [7, 13].
    Hit h2 = accel.intersect(Ray(Vec3(12.5f, 2.5f, 5.f), Vec3(0, 0, -1)));
    ASSERT_TRUE(h2.valid());
    EXPECT_EQ(h2.instance_id, 1u);
    EXPECT_NEAR(h2.t, 5.f, 1e-5f);
    // Rigid motion: only the instance transform changes.
    accel.set_instance_transform(0, Mat4::translate(0, 0, -1));
    accel.commit();
    EXPECT_NEAR(accel.intersect(Ray(Vec3(0.f, 0.f, 5.f), Vec3(0, 0, -1))).t, 6.f, 1e-5f);
}

TEST_F(AccelFixture, UpdateMeshPointsRefits) {
    accel.add_instance(mesh, Mat4());
    accel.commit();
    std::vector<float> moved = pts;
    for (int i = 0; i < 4; ++i) moved[3 * i + 2] = 1.5f;
    accel.update_mesh_points(mesh, moved.data());
    accel.commit();
    EXPECT_NEAR(accel.intersect(Ray(Vec3(0.f, 0.f, 5.f), Vec3(0, 0, -1))).t, 3.5f, 1e-5f);
}

TEST(Accel, PacketsMatchScalar) {
    // A cube and a quad, rotated/scaled instances, random rays; some lanes inactive.
    MeshData cube = cube_mesh(1.f);
    Accel accel;
    uint32_t m = accel.add_mesh(cube.points, cube.n_points, cube.indices, cube.n_tris);
    accel.add_instance(m, Mat4());
    accel.add_instance(m, Mat4::translate(3, 0, 0) * Mat4::rotate(30, 1, 1, 0) * Mat4::scale(0.5, 1, 2));
    accel.commit();
    ASSERT_GE(Accel::max_packet_width(), 4);
    int checked_hits = 0;
    for (int width : {4, 8, 16}) {
        for (int batch = 0; batch < 200; ++batch) {
            Ray rays[16];
            alignas(64) int valid[16];
            for (int i = 0; i < width; ++i) {
                uint32_t k = uint32_t(batch * 16 + i);
                Vec2 u = uniform2(20 + width, k), v = uniform2(40 + width, k);
                Vec3 o = Vec3(1.5f, 0.f, 0.f) + square_to_uniform_sphere(u) * 6.f;
                Vec3 target(3.f * v.x, 2.f * v.y - 1.f, 0.f);
                rays[i] = Ray(o, normalize(target - o), 0.f, (k % 7 == 0) ? 3.f : k_infinity);
                valid[i] = (k % 5 != 3);
            }
            Hit hits[16];
            bool occ[16];
            accel.intersect_packet(width, valid, rays, hits);
            accel.occluded_packet(width, valid, rays, occ);
            for (int i = 0; i < width; ++i) {
                if (!valid[i]) {
                    EXPECT_FALSE(hits[i].valid());
                    EXPECT_FALSE(occ[i]);
                    continue;
                }
                Hit s = accel.intersect(rays[i]);
                ASSERT_EQ(s.valid(), hits[i].valid()) << "width " << width << " lane " << i;
                EXPECT_EQ(accel.occluded(rays[i]), occ[i]);
                if (s.valid()) {
                    ++checked_hits;
                    EXPECT_NEAR(s.t, hits[i].t, 1e-5f * std::max(1.f, s.t));  // ISAs differ by an ulp
                    EXPECT_EQ(s.instance_id, hits[i].instance_id);
                    EXPECT_EQ(s.prim_id, hits[i].prim_id);
                    EXPECT_NEAR(s.u, hits[i].u, 1e-4f);
                    EXPECT_NEAR(s.v, hits[i].v, 1e-4f);
                }
            }
        }
    }
    EXPECT_GT(checked_hits, 500);  // the comparison is not vacuous
    Ray r[4];
    int v[4] = {1, 1, 1, 1};
    Hit h[4];
    EXPECT_THROW(accel.intersect_packet(5, v, r, h), std::invalid_argument);
}
