// Thin-lens depth of field: pinhole unchanged without an open aperture (bit for bit),
// the lens radius from f_stop / focal length / lens unit, rays of one pixel converge on
// the plane of focus, and an out-of-focus point spreads over the circle of confusion
// that geometric optics predicts. Deterministic checks (no false alarms).
#include "test_util.h"

#include "cameras/camera.h"
#include "integrators/common/render.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

using namespace cmlt;
using namespace cmlt::test;

namespace {

CameraDesc lens_camera(const Mat4& xf, float f_stop, float focus) {
    CameraDesc c = camera_at(xf, 50.f, 36.f);
    c.f_stop = f_stop;
    c.focus_distance = focus;
    c.lens_unit = 0.001f;  // mm
    return c;
}

bool same_ray(const Ray& a, const Ray& b) {
    return std::memcmp(&a.o, &b.o, sizeof(Vec3)) == 0 && std::memcmp(&a.d, &b.d, sizeof(Vec3)) == 0 &&
           a.tnear == b.tnear && a.tfar == b.tfar;
}

}  // namespace

TEST(ThinLens, PinholeUnchangedWithoutAperture) {
    Mat4 xf = Mat4::translate(0.3, -0.2, 4) * Mat4::rotate(20, 0.2, 1, 0);
    for (auto [f_stop, focus] : {std::pair{0.f, 3.f}, std::pair{2.8f, 0.f}, std::pair{0.f, 0.f}}) {
        Camera cam(lens_camera(xf, f_stop, focus), 64, 48);
        EXPECT_FALSE(cam.has_lens());
        for (uint32_t i = 0; i < 100; ++i) {
            Vec2 p = uniform2(400, i);
            p = Vec2(p.x * 64, p.y * 48);
            EXPECT_TRUE(same_ray(cam.generate_ray(p), cam.generate_ray(p, uniform2(401, i))));
        }
    }
    // Rendering: f_stop 0 gives the image of the camera without the fields, bit for bit.
    Scene s;
    s.set_materials({Material{Spectrum(0.7f), Spectrum(0.f)}, Material{Spectrum(0.f), Spectrum(5.f)}});
    uint32_t m = s.add_mesh("/floor", quad_mesh(Vec3(0.f), Vec3(2, 0, 0), Vec3(0, 0, -2)));
    s.add_instance(m, Mat4());
    uint32_t l = s.add_mesh("/lamp", quad_mesh(Vec3(0, 1, 0), Vec3(0.3f, 0, 0), Vec3(0, 0, 0.3f), 1));
    s.add_instance(l, Mat4());
    CameraDesc c = camera_at(Mat4::translate(0, 0.8, 2.5) * Mat4::rotate(-15, 1, 0, 0), 20.f, 36.f);
    s.set_camera(c);
    s.commit();
    RenderSettings st;
    st.width = 16;
    st.height = 16;
    st.spp = 4;
    st.threads = 2;
    for (const char* integ : {"pt", "bdpt"}) {
        st.integrator = integ;
        RenderResult a = render(s, st);
        c.focus_distance = 2.f;  // f_stop still 0: pinhole
        s.set_camera(c);
        RenderResult b = render(s, st);
        c.focus_distance = 0.f;
        s.set_camera(c);
        EXPECT_EQ(std::memcmp(a.image.data(), b.image.data(), a.image.size() * sizeof(float)), 0)
            << integ;
    }
}

TEST(ThinLens, RadiusAndConvergenceOnThePlaneOfFocus) {
    const float focus = 3.f;
    Mat4 xf = Mat4::translate(0.5, 1, 2) * Mat4::rotate(30, 1, 0.5, 0.2);
    Camera cam(lens_camera(xf, 2.f, focus), 64, 48);
    ASSERT_TRUE(cam.has_lens());
    EXPECT_NEAR(cam.lens_radius(), 50.f * 0.001f / (2.f * 2.f), 1e-7f);  // 12.5 mm
    Mat4 inv = xf.inverse();
    for (uint32_t i = 0; i < 50; ++i) {
        Vec2 p = uniform2(402, i);
        p = Vec2(p.x * 64, p.y * 48);
        Ray pin = cam.generate_ray(p);
        // The pinhole ray's point at depth `focus` (camera space z = -focus).
        Vec3 dc = inv.transform_vector(pin.d);
        Vec3 target = pin.o + pin.d * (focus / -dc.z);
        float max_lens = 0.f;
        for (uint32_t k = 0; k < 50; ++k) {
            Ray r = cam.generate_ray(p, uniform2(403, i * 50 + k));
            Vec3 oc = inv.transform_point(r.o);
            EXPECT_NEAR(oc.z, 0.f, 1e-5f);
            float rl = std::sqrt(oc.x * oc.x + oc.y * oc.y);
            EXPECT_LE(rl, cam.lens_radius() * (1 + 1e-5f));
            max_lens = std::max(max_lens, rl);
            EXPECT_NEAR(length(r.d), 1.f, 1e-5f);
            Vec3 rd = inv.transform_vector(r.d);
            Vec3 hit = r.o + r.d * ((focus - 0.f) / -rd.z - oc.z / rd.z);
            EXPECT_LT(length(hit - target), 2e-5f * focus) << "pixel " << p.x << "," << p.y;
        }
        EXPECT_GT(max_lens, 0.5f * cam.lens_radius());  // the lens is really sampled
    }
}

TEST(ThinLens, CircleOfConfusion) {
    // Camera at the origin looking down -Z; a point P on the axis at depth z0. Through a
    // lens point L, P is seen at the raster position of Q = P F/z0 + L (1 - F/z0) (the
    // ray L -> P meets the plane of focus there). Over the lens rim these positions form
    // a circle of diameter 2 r |z0 - F| / z0 * f / F in aperture units (mm) on the
    // sensor: the circle of confusion.
    const float F = 2.f, f = 50.f, ha = 36.f, N = 1.4f;
    const int W = 512, H = 512;
    CameraDesc cd = lens_camera(Mat4(), N, F);
    Camera cam(cd, W, H);
    const float r = f * 0.001f / (2 * N);
    for (float z0 : {1.f, 1.5f, 4.f, 10.f}) {
        Vec3 P(0, 0, -z0);
        double coc_mm = 2.0 * r * std::fabs(z0 - F) / z0 * f / F;
        double coc_px = coc_mm / ha * W;
        double max_d = 0;
        for (int k = 0; k < 256; ++k) {
            // Lens samples on the rim: concentric map with u on the square's boundary.
            double a = (k + 0.5) / 256.0;
            Vec2 u = (k % 4 == 0) ? Vec2(float(a), 0.999999f)
                   : (k % 4 == 1) ? Vec2(0.999999f, float(a))
                   : (k % 4 == 2) ? Vec2(float(a), 0.f)
                                  : Vec2(0.f, float(a));
            Ray centre = cam.generate_ray(Vec2(W / 2.f, H / 2.f), u);
            Vec3 L = centre.o;  // the lens point of sample u (independent of the pixel)
            EXPECT_NEAR(std::sqrt(L.x * L.x + L.y * L.y), r, 1e-4f * r);
            Vec3 Q = P * (F / z0) + L * (1 - F / z0);
            Vec2 pr;
            ASSERT_TRUE(cam.world_to_raster(Q, &pr));
            // The camera's ray through (pr, u) passes through P.
            Ray ray = cam.generate_ray(pr, u);
            EXPECT_LT(length(ray.o - L), 1e-6f);
            Vec3 to = P - ray.o;
            float off = length(to - ray.d * dot(to, ray.d));
            EXPECT_LT(off, 1e-5f * z0) << "z0 " << z0;
            max_d = std::max(max_d, double(length(Vec3(pr.x - W / 2.f, pr.y - H / 2.f, 0.f))));
        }
        EXPECT_NEAR(2 * max_d, coc_px, 1e-3 * coc_px + 1e-3) << "z0 " << z0;
        std::printf("[thin lens] z0 %.1f m: circle of confusion %.3f px (optics %.3f px)\n", z0,
                    2 * max_d, coc_px);
    }
}
