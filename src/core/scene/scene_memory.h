#pragma once
/// \file What a committed scene's geometry costs in memory, per triangle.
///
/// Two parts: the BVHs Embree built (counted by the device's memory monitor around each
/// commit, accel/accel.h) and the mesh arrays the core reads at hits (points, indices,
/// normals, uvs, material ids, primvars: zero-copy views of the caller's arrays, counted
/// at their size) plus the core's own tables (emissive-triangle light map, world-space
/// points of static instances).
/// Triangles are those of the meshes (an instanced mesh counts once: that is what is
/// stored), so bytes_per_triangle = total / triangles.
#include <cstddef>
#include <cstdint>

namespace cmlt {

class Scene;

struct SceneMemory {
    uint64_t meshes = 0, instances = 0;
    uint64_t triangles = 0;          ///< sum over meshes
    uint64_t vertices = 0;           ///< sum over meshes
    uint64_t bvh_bytes = 0;          ///< mesh BVHs + top level (Embree)
    uint64_t top_level_bytes = 0;    ///< the top level alone (part of bvh_bytes)
    uint64_t point_bytes = 0;        ///< float32 x 3 per vertex (+ the spare row Embree reads)
    uint64_t index_bytes = 0;        ///< uint32 x 3 per triangle
    uint64_t normal_bytes = 0;       ///< float32 x 3 per vertex, when the mesh has normals
    uint64_t uv_bytes = 0;           ///< float32 x 2 per vertex, when the mesh has uvs
    uint64_t material_id_bytes = 0;  ///< uint32 per triangle, when the mesh has them
    uint64_t primvar_bytes = 0;      ///< float32 per vertex and primvar column
    uint64_t light_map_bytes = 0;    ///< int32 per triangle of instances with emitters
    uint64_t placed_point_bytes = 0; ///< float32 x 3 per vertex of meshes placed once,
                                     ///< statically: their world-space points (Scene::m_placed)
    uint64_t mesh_bytes() const {
        return point_bytes + index_bytes + normal_bytes + uv_bytes + material_id_bytes +
               primvar_bytes + light_map_bytes + placed_point_bytes;
    }
    uint64_t total_bytes() const { return bvh_bytes + mesh_bytes(); }
    double bytes_per_triangle() const {
        return triangles ? double(total_bytes()) / double(triangles) : 0.0;
    }
};

/// The memory of `scene` after commit().
SceneMemory scene_memory(const Scene& scene);

}  // namespace cmlt
