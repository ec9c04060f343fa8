#pragma once
/// \file A triangle mesh in object space, sharing memory with its owner (numpy arrays).
#include "math/vec.h"
#include "scene/interaction.h"

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

namespace cmlt {

/// Raw views of the mesh arrays. Pointers stay valid as long as `owner` lives.
struct MeshData {
    const float* points = nullptr;         ///< (n_points, 3), + 4 readable bytes after
    size_t n_points = 0;
    const uint32_t* indices = nullptr;     ///< (n_tris, 3), CCW from the front
    size_t n_tris = 0;
    const float* normals = nullptr;        ///< (n_points, 3) or null
    const float* uvs = nullptr;            ///< (n_points, 2) or null
    const uint32_t* material_ids = nullptr;  ///< (n_tris,) or null: every triangle material_id_all
    uint32_t material_id_all = 0;            ///< the material of every triangle without material_ids
    /// (n_points, n_primvar_columns) per-vertex primvar values, or null: the columns that
    /// material inputs driven by a UsdPrimvarReader read (Material::pv_*), interpolated
    /// at a hit into SurfaceInteraction::primvars. At most k_max_primvar_columns.
    const float* primvars = nullptr;
    uint32_t n_primvar_columns = 0;
    std::shared_ptr<void> owner;           ///< keeps the arrays alive (set by the bindings)
};

/// The texture coordinates of a hit at barycentrics (b0, b1, b2) of a triangle whose
/// corners' uvs are t[0..2] (t[0] null: the mesh has none, and (b1, b2) stand in).
inline Vec2 hit_uv(const float* const t[3], float b0, float b1, float b2) {
    if (!t[0]) return Vec2(b1, b2);
    return Vec2(t[0][0] * b0 + t[1][0] * b1 + t[2][0] * b2, t[0][1] * b0 + t[1][1] * b1 + t[2][1] * b2);
}

struct Mesh {
    std::string name;
    MeshData data;
    Vec3 bbox_min, bbox_max;  ///< object-space bounds of the points

    Vec3 point(uint32_t i) const {
        const float* p = data.points + 3 * size_t(i);
        return {p[0], p[1], p[2]};
    }
    Vec3 normal(uint32_t i) const {
        const float* n = data.normals + 3 * size_t(i);
        return {n[0], n[1], n[2]};
    }
    Vec2 uv(uint32_t i) const {
        const float* t = data.uvs + 2 * size_t(i);
        return {t[0], t[1]};
    }
    const float* primvar_row(uint32_t i) const {
        return data.primvars + size_t(data.n_primvar_columns) * size_t(i);
    }
    void triangle(uint32_t prim, uint32_t v[3]) const {
        const uint32_t* t = data.indices + 3 * size_t(prim);
        v[0] = t[0]; v[1] = t[1]; v[2] = t[2];
    }
    uint32_t material_id(uint32_t prim) const {
        return data.material_ids ? data.material_ids[prim] : data.material_id_all;
    }
};

}  // namespace cmlt
