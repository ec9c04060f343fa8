// Coordinates the renderer cannot trace (scene/coordinate_range.h) are refused at
// commit with an error naming the mesh, the camera or the light, instead of reaching
// Embree (which aborts the process on rays beyond its range); sane extremes still
// commit and trace.
#include "test_util.h"

#include "scene/coordinate_range.h"
#include "util/error.h"

#include <gtest/gtest.h>

using namespace cmlt;
using namespace cmlt::test;

namespace {

std::string commit_error(Scene& s) {
    try {
        s.commit();
    } catch (const SceneError& e) {
        return e.what();
    }
    return "";
}

MeshData quad(float half) {
    return quad_mesh(Vec3(0.f), Vec3(half, 0, 0), Vec3(0, half, 0));
}

}  // namespace

TEST(CoordinateRange, AffineReach) {
    EXPECT_DOUBLE_EQ(affine_reach(Mat4(), 2.0), 2.0);
    EXPECT_DOUBLE_EQ(affine_reach(Mat4::translate(0, -5, 1) * Mat4::scale(3, 1, 1), 2.0), 7.0);
    EXPECT_DOUBLE_EQ(affine_reach(Mat4::scale(1, 1, 1e-30).inverse(), 1.0), 1e30);
    EXPECT_TRUE(std::isinf(max_abs(Vec3(0.f), Vec3(NAN, 0, 0))));
}

TEST(CoordinateRange, FarPointsAreRefusedNamingTheMesh) {
    Scene s;
    s.add_instance(s.add_mesh("/World/far", quad(4e16f)), Mat4());
    std::string msg = commit_error(s);
    EXPECT_NE(msg.find("/World/far"), std::string::npos) << msg;
    EXPECT_NE(msg.find("points reach"), std::string::npos) << msg;
}

TEST(CoordinateRange, FarInstancesAreRefusedNamingTheMesh) {
    Scene s;
    s.add_instance(s.add_mesh("/World/moved", quad(1.f)), Mat4::translate(0, 3.2e16, 0));
    std::string msg = commit_error(s);
    EXPECT_NE(msg.find("/World/moved"), std::string::npos) << msg;
    EXPECT_NE(msg.find("world-space"), std::string::npos) << msg;
}

TEST(CoordinateRange, DegenerateScaleIsRefusedNamingTheMesh) {
    Scene s;
    s.add_instance(s.add_mesh("/World/ground", quad(5.f)), Mat4());
    s.add_instance(s.add_mesh("/World/flat", quad(1.f)), Mat4::scale(1e-30, 1.5, 5.5));
    std::string msg = commit_error(s);
    EXPECT_NE(msg.find("/World/flat"), std::string::npos) << msg;
    EXPECT_NE(msg.find("degenerate"), std::string::npos) << msg;
    // the same in a motion step
    Scene m;
    uint32_t mesh = m.add_mesh("/World/squash", quad(1.f));
    uint32_t inst = m.add_instance(mesh, Mat4());
    m.set_instance_motion(inst, {Mat4(), Mat4::scale(1, 1e-30, 1)});
    msg = commit_error(m);
    EXPECT_NE(msg.find("/World/squash"), std::string::npos) << msg;
}

TEST(CoordinateRange, FarCameraAndLightAreRefused) {
    Scene s;
    s.add_instance(s.add_mesh("/World/q", quad(1.f)), Mat4());
    try {
        s.set_camera(camera_at(Mat4::translate(0, 0, 2e15)));
        ADD_FAILURE() << "a camera at 2e15 was accepted";
    } catch (const SceneError& e) {
        EXPECT_NE(std::string(e.what()).find("set_camera"), std::string::npos) << e.what();
    }
    LightDesc far;
    far.kind = LightDesc::Kind::sphere;
    far.transform = Mat4::translate(5e15, 0, 0);
    try {
        s.add_light(far);
        ADD_FAILURE() << "a light at 5e15 was accepted";
    } catch (const SceneError& e) {
        EXPECT_NE(std::string(e.what()).find("add_light"), std::string::npos) << e.what();
    }
    LightDesc sun;  // distant and dome lights have no position
    sun.kind = LightDesc::Kind::distant;
    sun.transform = Mat4::translate(5e15, 0, 0);
    EXPECT_NO_THROW(s.add_light(sun));
}

TEST(CoordinateRange, SaneExtremesCommitAndTrace) {
    // a 1e5-scale room, a 1e-4-scale one, and a flattening scale of 1e-6
    for (double k : {1e5, 1e-4}) {
        Scene s;
        s.add_instance(s.add_mesh("/World/floor", quad(4.f)), Mat4::scale(k, k, k));
        s.add_instance(s.add_mesh("/World/disk", quad(1.f)),
                       Mat4::translate(0, 0, k) * Mat4::scale(k, k, 1e-6 * k));
        s.set_camera(camera_at(Mat4::translate(0, 0, 3 * k)));
        EXPECT_EQ(commit_error(s), "") << k;
        SurfaceInteraction si;
        ASSERT_TRUE(s.intersect_surface(Ray(Vec3(0.1f * float(k), 0, 2.f * float(k)), Vec3(0, 0, -1)), &si)) << k;
        EXPECT_NEAR(si.p.z, k, 1e-3 * k) << k;
    }
}
