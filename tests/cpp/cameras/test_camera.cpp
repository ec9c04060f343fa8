// Camera: raster -> ray -> world point -> raster round trip; framing; orthographic.
#include "test_util.h"

#include "cameras/camera.h"
#include "util/error.h"

#include <gtest/gtest.h>

using namespace cmlt;
using namespace cmlt::test;

namespace {

void round_trip(const CameraDesc& desc, int w, int h) {
    Camera cam(desc, w, h);
    for (uint32_t i = 0; i < 500; ++i) {
        Vec2 u = uniform2(60, i);
        Vec2 raster(u.x * w, u.y * h);
        Ray r = cam.generate_ray(raster);
        ASSERT_NEAR(length(r.d), 1.f, 1e-5f);
        float t = 0.5f + 20.f * uniform2(61, i).x;
        Vec2 back;
        ASSERT_TRUE(cam.world_to_raster(r.at(t), &back));
        EXPECT_NEAR(back.x, raster.x, 2e-3f * w) << i;
        EXPECT_NEAR(back.y, raster.y, 2e-3f * h) << i;
    }
}

}  // namespace

TEST(Camera, PerspectiveRoundTrip) {
    CameraDesc d = camera_at(Mat4::translate(1, 2, 3) * Mat4::rotate(35, 0.3, 1, 0.2), 35.f, 36.f);
    d.horizontal_aperture_offset = 2.f;
    d.vertical_aperture_offset = -1.f;
    round_trip(d, 64, 48);
    round_trip(d, 31, 77);
}

TEST(Camera, OrthographicRoundTrip) {
    CameraDesc d = camera_at(Mat4::translate(0, 1, 5) * Mat4::rotate(-20, 1, 0, 0), 50.f, 20.f);
    d.projection = CameraDesc::Projection::orthographic;
    round_trip(d, 40, 30);
}

TEST(Camera, FramingFitsTheHorizontalAperture) {
    // focal 18, aperture 36: the image's left/right edges are at 45 degrees; the
    // vertical extent follows the image aspect (2:1 here), whatever vertical_aperture says.
    CameraDesc d = camera_at(Mat4(), 18.f, 36.f);
    d.vertical_aperture = 5.f;
    Camera cam(d, 200, 100);
    Vec3 right = cam.generate_ray(Vec2(200.f, 50.f)).d;
    EXPECT_NEAR(right.x, std::sqrt(0.5f), 1e-5f);
    EXPECT_NEAR(right.z, -std::sqrt(0.5f), 1e-5f);
    Vec3 top = cam.generate_ray(Vec2(100.f, 0.f)).d;
    EXPECT_NEAR(top.y / -top.z, 0.5f, 1e-5f);  // +Y is up, row 0 is the top
    Vec3 centre = cam.generate_ray(Vec2(100.f, 50.f)).d;
    EXPECT_NEAR(centre.z, -1.f, 1e-6f);
    Vec2 r;
    EXPECT_FALSE(cam.world_to_raster(Vec3(0, 0, 1), &r));  // behind the camera
}

TEST(Camera, NearClipAlongTheRay) {
    CameraDesc d = camera_at(Mat4(), 18.f, 36.f);
    d.near = 2.f;
    Camera cam(d, 10, 10);
    Ray r = cam.generate_ray(Vec2(10.f, 5.f));  // 45 degrees: depth 2 at t = 2 sqrt 2
    EXPECT_NEAR(r.tnear, 2.f * std::sqrt(2.f), 1e-5f);
}

TEST(Camera, BadParametersThrow) {
    CameraDesc d = camera_at(Mat4());
    d.focal_length = 0.f;
    EXPECT_THROW(d.validate(), SceneError);
    d = camera_at(Mat4());
    d.far = d.near;
    EXPECT_THROW(d.validate(), SceneError);
    d = camera_at(Mat4::scale(0, 1, 1));
    EXPECT_THROW(d.validate(), SceneError);
}
