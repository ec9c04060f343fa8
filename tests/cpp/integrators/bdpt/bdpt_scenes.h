#pragma once
// The scenes of the BDPT tests (test_bdpt.cpp, test_bdpt_mis.cpp): the Cornell box
// (also through a thin lens and with a moving block), a sphere light in the box, and
// a floor and block under a dome and a sun.
#include "test_scenes.h"

#include "scene/scene.h"

namespace cmlt::test {

inline void cornell(Scene& s) {
    box_scene(s, 12.f, true);
    s.commit();
}

/// The Cornell box through a thin lens (r = 16 mm * 0.01 / (2 * 2) = 4 cm, focus 1.2 m).
inline void cornell_lens(Scene& s) {
    box_scene(s, 12.f, true);
    CameraDesc c = s.camera_desc();
    c.f_stop = 2.f;
    c.focus_distance = 1.2f;
    c.lens_unit = 0.01f;
    s.set_camera(c);
    s.commit();
}

/// The Cornell box whose block slides 0.9 m along x while the shutter is open.
inline void moving_block_box(Scene& s) {
    box_scene(s, 12.f, true);
    const Mat4 r = Mat4::rotate(25, 0, 1, 0);
    s.set_instance_motion(2, {Mat4::translate(-0.5, -0.7, -0.3) * r, Mat4::translate(0.4, -0.7, -0.3) * r});
    s.commit();
}

inline void sphere_light_box(Scene& s) {
    box_scene(s, 0.f, false);
    LightDesc sph;
    sph.kind = LightDesc::Kind::sphere;
    sph.transform = Mat4::translate(-0.4, 0.6, -0.2);
    sph.radius = 0.08f;
    sph.radiance = Spectrum(60.f, 50.f, 40.f);
    s.add_light(sph);
    s.commit();
}

inline void dome_scene(Scene& s) {
    s.set_materials({Material{Spectrum(0.6f, 0.5f, 0.4f), Spectrum(0.f)},
                     Material{Spectrum(0.3f, 0.5f, 0.7f), Spectrum(0.f)}});
    uint32_t floor = s.add_mesh("/floor", quad_mesh(Vec3(0.f), Vec3(3, 0, 0), Vec3(0, 0, -3)));
    s.add_instance(floor, Mat4());
    uint32_t b = s.add_mesh("/block", cube_mesh(0.5f, 1));
    s.add_instance(b, Mat4::translate(0, 0.5, 0) * Mat4::rotate(30, 0, 1, 0));
    add_dome_and_sun(s, Spectrum(0.8f, 0.9f, 1.f), Spectrum(300.f), 5.f, Mat4::rotate(-50, 1, 0.3, 0));
    s.set_camera(camera_at(Mat4::translate(0, 1.5, 3.5) * Mat4::rotate(-20, 1, 0, 0), 20.f, 36.f));
    s.commit();
}

}  // namespace cmlt::test
