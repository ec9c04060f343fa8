#pragma once
// Small helpers shared by the test files: deterministic uniform numbers, scene builders.
#include "math/mat4.h"
#include "sampling/rng.h"
#include "scene/scene.h"

#include <memory>
#include <vector>

namespace cmlt::test {

/// Deterministic uniform numbers for tests: stream `test_id`, index i.
inline Vec2 uniform2(uint32_t test_id, uint32_t i) {
    auto r = philox4x32(pixel_counter(i, test_id, 0, RngStream::test), {0x1234u, 0x5678u});
    return {uint_to_unit_float(r[0]), uint_to_unit_float(r[1])};
}

/// A mesh whose arrays live in a shared_ptr owner (with the spare padding row).
struct OwnedMesh {
    std::vector<float> points;       // (n + 1) * 3, last row padding
    std::vector<uint32_t> indices;
    std::vector<uint32_t> material_ids;
    std::vector<float> normals;
};

inline MeshData make_mesh_data(const std::vector<Vec3>& pts, const std::vector<uint32_t>& idx,
                               const std::vector<uint32_t>& mat_ids = {},
                               const std::vector<Vec3>& normals = {}) {
    auto m = std::make_shared<OwnedMesh>();
    for (const Vec3& p : pts) { m->points.push_back(p.x); m->points.push_back(p.y); m->points.push_back(p.z); }
    m->points.insert(m->points.end(), {0.f, 0.f, 0.f});
    m->indices = idx;
    m->material_ids = mat_ids;
    for (const Vec3& n : normals) { m->normals.push_back(n.x); m->normals.push_back(n.y); m->normals.push_back(n.z); }
    MeshData d;
    d.points = m->points.data();
    d.n_points = pts.size();
    d.indices = m->indices.data();
    d.n_tris = idx.size() / 3;
    d.material_ids = mat_ids.empty() ? nullptr : m->material_ids.data();
    d.normals = normals.empty() ? nullptr : m->normals.data();
    d.owner = m;
    return d;
}

/// A sphere light of `radius` at `center` with uniform `radiance`.
inline LightDesc sphere_light(const Vec3& center, float radius, const Spectrum& radiance) {
    LightDesc sph;
    sph.kind = LightDesc::Kind::sphere;
    sph.transform = Mat4::translate(center.x, center.y, center.z);
    sph.radius = radius;
    sph.radiance = radiance;
    return sph;
}

/// Quad centred at c spanned by half-edges u, v; normal u x v (CCW).
inline MeshData quad_mesh(const Vec3& c, const Vec3& u, const Vec3& v, uint32_t material = 0) {
    return make_mesh_data({c - u - v, c + u - v, c + u + v, c - u + v}, {0, 1, 2, 0, 2, 3},
                          {material, material});
}

/// Axis-aligned cube [-h, h]^3, 12 triangles.
inline MeshData cube_mesh(float h, uint32_t material = 0) {
    std::vector<Vec3> p;
    for (int i = 0; i < 8; ++i) p.push_back(Vec3(i & 1 ? h : -h, i & 2 ? h : -h, i & 4 ? h : -h));
    std::vector<uint32_t> idx = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                                 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
    return make_mesh_data(p, idx, std::vector<uint32_t>(12, material));
}

/// Camera at `pos` looking down -Z (identity rotation) unless a transform is given.
inline CameraDesc camera_at(const Mat4& xf, float focal = 18.f, float aperture = 36.f) {
    CameraDesc c;
    c.transform = xf;
    c.focal_length = focal;
    c.horizontal_aperture = aperture;
    c.vertical_aperture = aperture;
    return c;
}

}  // namespace cmlt::test
