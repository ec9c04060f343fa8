#include "scene/scene_memory.h"

#include "scene/scene.h"

namespace cmlt {

SceneMemory scene_memory(const Scene& scene) {
    SceneMemory m;
    const Accel& accel = scene.accel();
    m.meshes = scene.mesh_count();
    m.instances = scene.instance_count();
    m.top_level_bytes = accel.top_level_bytes();
    m.bvh_bytes = m.top_level_bytes;
    for (uint32_t i = 0; i < scene.mesh_count(); ++i) {
        const MeshData& d = scene.mesh(i).data;
        const uint64_t nv = d.n_points, nt = d.n_tris;
        m.triangles += nt;
        m.vertices += nv;
        m.bvh_bytes += accel.mesh_bvh_bytes(i);
        m.point_bytes += 3 * sizeof(float) * (nv + 1);
        m.index_bytes += 3 * sizeof(uint32_t) * nt;
        if (d.normals) m.normal_bytes += 3 * sizeof(float) * nv;
        if (d.uvs) m.uv_bytes += 2 * sizeof(float) * nv;
        if (d.material_ids) m.material_id_bytes += sizeof(uint32_t) * nt;
        if (d.primvars) m.primvar_bytes += sizeof(float) * uint64_t(d.n_primvar_columns) * nv;
    }
    m.placed_point_bytes = scene.placed_point_bytes();
    m.light_map_bytes = scene.light_map_entries() * sizeof(int32_t);
    return m;
}

}  // namespace cmlt
