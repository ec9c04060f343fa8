#pragma once
// Small scenes several test areas render: the Cornell-like box (optionally with
// pass-through surfaces and a point light), a smooth glass ball on a floor.
#include "test_util.h"

#include "math/safe_math.h"
#include "scene/scene.h"

#include <cmath>
#include <vector>

namespace cmlt::test {

/// A uniform dome of radiance `dome`, then a distant light of radiance `sun` whose
/// direction is `orient` applied to -Z and whose cone is `angle` degrees (0: delta).
inline void add_dome_and_sun(Scene& s, Spectrum dome, Spectrum sun, float angle, const Mat4& orient) {
    LightDesc d;
    d.kind = LightDesc::Kind::dome;
    d.radiance = dome;
    s.add_light(d);
    LightDesc sun_light;
    sun_light.kind = LightDesc::Kind::distant;
    sun_light.angle = angle;
    sun_light.radiance = sun;
    sun_light.transform = orient;
    s.add_light(sun_light);
}

/// Cube [-1,1]^3 seen from inside: coloured walls (Cornell-like), camera at +Z looking -Z.
/// Materials: 0 white, 1 red, 2 green, 3 emitter (le).
inline void box_scene(Scene& s, float le, bool emissive_quad) {
    s.set_materials({Material{Spectrum(0.7f), Spectrum(0.f)},
                     Material{Spectrum(0.7f, 0.15f, 0.1f), Spectrum(0.f)},
                     Material{Spectrum(0.1f, 0.6f, 0.15f), Spectrum(0.f)},
                     Material{Spectrum(0.5f), Spectrum(le)}});
    MeshData cube = cube_mesh(1.f);
    auto* mids = const_cast<uint32_t*>(cube.material_ids);
    // Triangle pairs of cube_mesh: 0-1 z=-1, 2-3 z=+1, 4-5 y=-1, 6-7 y=+1, 8-9 x=-1, 10-11 x=+1.
    mids[8] = mids[9] = 1;
    mids[10] = mids[11] = 2;
    uint32_t m = s.add_mesh("/box", std::move(cube));
    s.add_instance(m, Mat4());
    if (emissive_quad) {
        uint32_t q = s.add_mesh("/lamp", quad_mesh(Vec3(0, 0.98f, 0), Vec3(0.3f, 0, 0), Vec3(0, 0, 0.3f), 3));
        s.add_instance(q, Mat4());
    }
    uint32_t b = s.add_mesh("/block", cube_mesh(0.3f, 0));
    s.add_instance(b, Mat4::translate(0.3, -0.7, -0.3) * Mat4::rotate(25, 0, 1, 0));
    s.set_camera(camera_at(Mat4::translate(0, 0, 0.95), 16.f, 36.f));
}

/// The Cornell box with two pass-through surfaces in the light's way: a
/// fully cut-out quad under the lamp (opacity 0 below opacityThreshold 0.5) and a
/// partly transparent ior-1 quad across the box (opacity 0.4, diffuse 0.5: pass-through
/// lobe probability < 1, weight 0.6); a point light behind the latter; and an emissive
/// half-transparent ior-1 panel, which stays an ordinary Dirac transmission (emissive
/// materials do not pass rays, so that s = 0 sees their emission).
inline void pass_through_box(Scene& s) {
    box_scene(s, 12.f, true);
    std::vector<Material> mats = {Material{Spectrum(0.7f), Spectrum(0.f)},
                                  Material{Spectrum(0.7f, 0.15f, 0.1f), Spectrum(0.f)},
                                  Material{Spectrum(0.1f, 0.6f, 0.15f), Spectrum(0.f)},
                                  Material{Spectrum(0.5f), Spectrum(12.f)}};
    Material cut;
    cut.preview = true;
    cut.diffuse = Spectrum(0.6f);
    cut.opacity = 0.f;
    cut.opacity_threshold = 0.5f;
    Material veil;
    veil.preview = true;
    veil.diffuse = Spectrum(0.5f);
    veil.opacity = 0.4f;
    veil.ior = 1.f;
    Material glow = veil;
    glow.opacity = 0.5f;
    glow.emission = Spectrum(2.f, 1.5f, 1.f);
    mats.push_back(cut);   // 4
    mats.push_back(veil);  // 5
    mats.push_back(glow);  // 6
    s.set_materials(mats);
    uint32_t g = s.add_mesh("/glow", quad_mesh(Vec3(0.7f, -0.5f, 0.3f), Vec3(0, 0, 0.2f), Vec3(0, 0.2f, 0), 6));
    s.add_instance(g, Mat4());
    uint32_t c = s.add_mesh("/cutout", quad_mesh(Vec3(0, 0.7f, 0), Vec3(0.6f, 0, 0), Vec3(0, 0, 0.6f), 4));
    s.add_instance(c, Mat4());
    uint32_t v = s.add_mesh("/veil", quad_mesh(Vec3(0, 0, -0.2f), Vec3(0.95f, 0, 0), Vec3(0, 0.95f, 0), 5));
    s.add_instance(v, Mat4());
    LightDesc pt;
    pt.kind = LightDesc::Kind::sphere;
    pt.treat_as_point = true;
    pt.radius = 0.05f;
    pt.radiance = Spectrum(300.f);
    pt.transform = Mat4::translate(-0.4, 0.3, -0.7);
    s.add_light(pt);
    s.commit();
}

/// UV sphere of radius r (smooth vertex normals), n_theta x n_phi quads.
inline MeshData sphere_mesh(float r, int n_theta, int n_phi, uint32_t material = 0) {
    std::vector<Vec3> p, n;
    std::vector<uint32_t> idx;
    for (int i = 0; i <= n_theta; ++i) {
        float th = k_pi * float(i) / float(n_theta);
        for (int j = 0; j <= n_phi; ++j) {
            float ph = 2.f * k_pi * float(j) / float(n_phi);
            Vec3 d(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
            p.push_back(d * r);
            n.push_back(d);
        }
    }
    auto at = [&](int i, int j) { return uint32_t(i * (n_phi + 1) + j); };
    for (int i = 0; i < n_theta; ++i)
        for (int j = 0; j < n_phi; ++j) {
            // Outward winding (normal = e1 x e2 points away from the centre).
            if (i > 0) idx.insert(idx.end(), {at(i, j), at(i, j + 1), at(i + 1, j)});
            if (i + 1 < n_theta) idx.insert(idx.end(), {at(i, j + 1), at(i + 1, j + 1), at(i + 1, j)});
        }
    return make_mesh_data(p, idx, std::vector<uint32_t>(idx.size() / 3, material), n);
}

/// Smooth glass: UsdPreviewSurface opacity 0, ior 1.5, roughness 0 (Dirac lobes only).
inline Material smooth_glass() {
    Material glass;
    glass.preview = true;
    glass.diffuse = Spectrum(0.f);
    glass.opacity = 0.f;
    glass.ior = 1.5f;
    glass.roughness = 0.f;
    return glass;
}

/// glass_scene without its light and commit: materials 0 the floor, 1 the glass, then
/// `extra` from index 2; the floor, the ball and the camera.
inline void glass_scene_unlit(Scene& s, const std::vector<Material>& extra = {}) {
    std::vector<Material> mats = {Material{Spectrum(0.7f), Spectrum(0.f)}, smooth_glass()};
    mats.insert(mats.end(), extra.begin(), extra.end());
    s.set_materials(mats);
    uint32_t f = s.add_mesh("/floor", quad_mesh(Vec3(0.f), Vec3(2, 0, 0), Vec3(0, 0, -2)));
    s.add_instance(f, Mat4());
    uint32_t b = s.add_mesh("/ball", sphere_mesh(0.4f, 24, 48, 1));
    s.add_instance(b, Mat4::translate(0, 0.41, 0));
    s.set_camera(camera_at(Mat4::translate(0, 1.3, 1.6) * Mat4::rotate(-38, 1, 0, 0), 22.f, 36.f));
}

/// Smooth glass sphere on a diffuse floor, lit by a sphere light: the caustic under the
/// ball is found by PT only through BSDF-sampled paths that hit the light, so the light
/// is fairly large.
inline void glass_scene(Scene& s) {
    glass_scene_unlit(s);
    s.add_light(sphere_light(Vec3(0.25f, 1.4f, -0.1f), 0.25f, Spectrum(12.f, 11.f, 9.f)));
    s.commit();
}

}  // namespace cmlt::test
