// Camera: raster -> ray -> world point -> raster round trip; framing; orthographic.
#include "test_util.h"

#include "cameras/camera.h"
#include "integrators/path/diffuse_lanes.h"
#include "util/error.h"

#include <gtest/gtest.h>

#include <memory>
#include <utility>
#include <vector>

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

TEST(Camera, PinholeLanesGiveGenerateRaysFloats) {
    // camera_directions (pt's camera rays in lanes, integrators/path/diffuse_lanes.h) is
    // Camera::generate_ray written for many film positions at once: the same floats, bit
    // for bit, for rotated, scaled and sheared cameras with aperture offsets, film
    // positions inside the raster and beyond it. Cameras with a lens or an orthographic
    // projection have no pinhole constants (their rays stay per lane).
    Mat4 shear;
    shear.m[0][1] = 0.3;
    std::vector<std::pair<CameraDesc, std::pair<int, int>>> cams;
    CameraDesc a = camera_at(Mat4::translate(1, 2, 3) * Mat4::rotate(35, 0.3, 1, 0.2), 35.f, 36.f);
    a.horizontal_aperture_offset = 2.f;
    a.vertical_aperture_offset = -1.f;
    cams.push_back({a, {64, 48}});
    CameraDesc b = camera_at(Mat4::translate(-40, 7, 300) * Mat4::rotate(-70, 1, 0.2, 0.5) * Mat4::scale(2, 0.5, 1) * shear,
                             12.f, 24.f);
    b.near = 0.37f;
    b.far = 2.5e4f;
    cams.push_back({b, {31, 77}});
    cams.push_back({camera_at(Mat4(), 85.f, 20.f), {128, 128}});
    std::unique_ptr<DiffuseLanes> L(new DiffuseLanes);
    const size_t n = DiffuseLanes::k_capacity;
    for (size_t c = 0; c < cams.size(); ++c) {
        const int w = cams[c].second.first, h = cams[c].second.second;
        const Camera cam(cams[c].first, w, h);
        PinholeConstants pc;
        ASSERT_TRUE(cam.pinhole_constants(&pc));
        for (uint32_t round = 0; round < 4; ++round) {
            for (size_t k = 0; k < n; ++k) {
                const Vec2 u = uniform2(70 + uint32_t(c), round * uint32_t(n) + uint32_t(k));
                L->film_x[k] = -2.f + u.x * float(w + 4);
                L->film_y[k] = -2.f + u.y * float(h + 4);
            }
            camera_directions(*L, n, pc);
            for (size_t k = 0; k < n; ++k) {
                const Ray r = cam.generate_ray(Vec2(L->film_x[k], L->film_y[k]));
                ASSERT_EQ(r.o.x, pc.origin.x);
                ASSERT_EQ(r.o.y, pc.origin.y);
                ASSERT_EQ(r.o.z, pc.origin.z);
                ASSERT_EQ(r.d.x, L->dx[k]) << "camera " << c << ", lane " << k;
                ASSERT_EQ(r.d.y, L->dy[k]) << "camera " << c << ", lane " << k;
                ASSERT_EQ(r.d.z, L->dz[k]) << "camera " << c << ", lane " << k;
                ASSERT_EQ(r.tnear, L->ray_tnear[k]) << "camera " << c << ", lane " << k;
                ASSERT_EQ(r.tfar, L->ray_tfar[k]) << "camera " << c << ", lane " << k;
            }
        }
    }
    CameraDesc lens = a;
    lens.f_stop = 2.8f;
    lens.focus_distance = 5.f;
    PinholeConstants pc;
    EXPECT_FALSE(Camera(lens, 64, 48).pinhole_constants(&pc));
    CameraDesc ortho = a;
    ortho.projection = CameraDesc::Projection::orthographic;
    EXPECT_FALSE(Camera(ortho, 64, 48).pinhole_constants(&pc));
}
