// Embree queries: known distances, instance transforms, misses, updates, and packet
// queries (4/8/16 with valid masks) agreeing with scalar queries, including a recorded
// packet that Embree's coherent mode got wrong.
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

namespace {

/// tests/python/integrators/test_pssmlt.py's Cornell box (2 m, open at +z, each quad its own instance), a lamp just
/// under the ceiling, and a large quad across the box at y = 1.6 (a cut-out in the
/// Python test that found the problem below).
void add_box_with_lamp(Accel& accel) {
    const std::vector<MeshData> quads = {
        quad_mesh(Vec3(0, 0, 0), Vec3(0, 0, 1), Vec3(1, 0, 0)),              // floor
        quad_mesh(Vec3(0, 2, 0), Vec3(1, 0, 0), Vec3(0, 0, 1)),              // ceiling
        quad_mesh(Vec3(0, 1, -1), Vec3(1, 0, 0), Vec3(0, 1, 0)),             // back
        quad_mesh(Vec3(-1, 1, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)),             // left
        quad_mesh(Vec3(1, 1, 0), Vec3(0, 0, 1), Vec3(0, 1, 0)),              // right
        quad_mesh(Vec3(0, 1.98f, 0), Vec3(0.3f, 0, 0), Vec3(0, 0, 0.3f)),    // lamp
        quad_mesh(Vec3(0, 1.6f, 0), Vec3(0.7f, 0, 0), Vec3(0, 0, 0.7f)),     // large quad
    };
    for (const MeshData& q : quads)
        accel.add_instance(accel.add_mesh(q.points, q.n_points, q.indices, q.n_tris), Mat4());
    accel.commit();
}

}  // namespace

TEST(Accel, PacketOfLightSubpathBouncesFindsFlatInstances) {
    // A packet recorded from coherent MLT (two light subpaths of one bundle, four lanes
    // each, starting above and below the lamp). With RTC_INTERSECT_CONTEXT_FLAG_COHERENT,
    // Embree 3.13 returned the floor (t = 2.13) for lanes 4-7 where rtcIntersect1 finds
    // the large quad (t = 0.41); without the flag (Accel's default) every lane agrees.
    Accel accel;
    add_box_with_lamp(accel);
    const float o[8][3] = {{0.307705f, 1.99999f, 0.143275f}, {0.28759f, 1.99999f, 0.210934f},
                           {0.298883f, 1.99999f, 0.0873157f}, {0.291427f, 1.99999f, 0.323182f},
                           {0.298184216f, 1.97999251f, 0.0359352231f}, {0.292500317f, 1.97999251f, 0.0470501035f},
                           {0.287449181f, 1.97999251f, 0.244599938f}, {0.264327466f, 1.97999251f, 0.126297802f}};
    const float d[8][3] = {{0.26424f, -0.912822f, 0.311342f}, {0.26424f, -0.912822f, 0.311342f},
                           {0.26424f, -0.912822f, 0.311342f}, {0.26424f, -0.912822f, 0.311342f},
                           {0.227086842f, -0.927567422f, -0.296731412f}, {0.22708714f, -0.927567363f, -0.296731472f},
                           {0.22708708f, -0.92756772f, -0.296731532f}, {0.22708714f, -0.927567482f, -0.296731561f}};
    for (int width : {8, 16}) {
        if (width > Accel::max_packet_width()) continue;
        Ray rays[16];
        alignas(64) int valid[16];
        for (int i = 0; i < width; ++i) {
            const int j = i % 8;
            rays[i] = Ray(Vec3(o[j][0], o[j][1], o[j][2]), Vec3(d[j][0], d[j][1], d[j][2]));
            valid[i] = -1;
        }
        Hit hits[16];
        bool occ[16];
        accel.intersect_packet(width, valid, rays, hits);
        accel.occluded_packet(width, valid, rays, occ);
        for (int i = 0; i < width; ++i) {
            const Hit s = accel.intersect(rays[i]);
            ASSERT_TRUE(s.valid());
            EXPECT_EQ(s.instance_id, hits[i].instance_id) << "width " << width << " lane " << i;
            EXPECT_EQ(s.prim_id, hits[i].prim_id) << "width " << width << " lane " << i;
            EXPECT_EQ(accel.occluded(rays[i]), occ[i]);
            if (i % 8 >= 4) {
                EXPECT_EQ(s.instance_id, 6u);  // the large quad, 0.41 away
            }
        }
    }
}

TEST(Accel, CoincidentInstancesGiveTheSameHitOnEveryBuild) {
    // Several coplanar meshes over the same square (bad input, but real: the
    // tests/data/usd/polygons.usda stage has four): a ray hits them all at the same t,
    // and which one Embree reports depends on the top-level BVH. Every fresh build must
    // answer the same, so that renders are repeatable from process to process; the top
    // level's former Morton build (RTC_BUILD_QUALITY_LOW) reported another instance in
    // about one process of 40. Builds with heaps of different layouts (the allocations
    // kept alive between them) stand in for different processes.
    const std::vector<float> quad = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 0 /*pad*/};
    const std::vector<uint32_t> tris = {0, 1, 2, 0, 2, 3};
    const std::vector<uint32_t> flipped = {0, 2, 1, 0, 3, 2};
    std::vector<std::pair<uint32_t, uint32_t>> first;
    std::vector<std::vector<char>> ballast;
    for (int build = 0; build < 64; ++build) {
        ballast.emplace_back(size_t(1 + 4093 * build % 65521));
        Accel accel;
        for (int k = 0; k < 6; ++k) {
            const uint32_t m = accel.add_mesh(quad.data(), 4, (k % 2 ? flipped : tris).data(), 2);
            accel.add_instance(m, Mat4());
        }
        accel.commit();
        std::vector<std::pair<uint32_t, uint32_t>> hits;
        for (int i = 0; i < 16; ++i)
            for (int j = 0; j < 16; ++j) {
                // on the diagonal shared by the two triangles as well as inside them
                const float x = (i + 0.5f) / 16.f, y = (j == i) ? x : (j + 0.5f) / 16.f;
                const Hit h = accel.intersect(Ray(Vec3(x, y, 3.f), Vec3(0, 0, -1)));
                ASSERT_TRUE(h.valid());
                hits.emplace_back(h.instance_id, h.prim_id);
            }
        if (build == 0)
            first = hits;
        else
            ASSERT_EQ(hits, first) << "build " << build;
    }
}
