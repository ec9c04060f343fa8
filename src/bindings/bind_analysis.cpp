// Bindings of the scene probes (src/core/analysis/scene_probes.h) that the frame's scene
// analysis (cmlt/analysis/effects.py) asks for caustic paths and visibility.
#include "bind_common.h"

#include "analysis/kernel_select.h"
#include "analysis/scene_probes.h"
#include "scene/scene.h"
#include "scene/scene_memory.h"
#include "util/error.h"

#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

namespace cmlt::bindings {

using namespace nb::literals;

namespace {

nb::dict probe_py(Scene& scene, int width, int height, uint64_t seed, uint32_t light_paths,
                  uint32_t targeted_paths, uint32_t camera_paths, uint32_t light_samples,
                  int max_chain, float specular_roughness) {
    ProbeOptions o;
    o.width = width;
    o.height = height;
    o.seed = seed;
    o.light_paths = light_paths;
    o.targeted_paths = targeted_paths;
    o.camera_paths = camera_paths;
    o.light_samples = light_samples;
    o.max_chain = max_chain;
    o.specular_roughness = specular_roughness;
    o.validate();
    if (!scene.has_camera()) CMLT_THROW(SceneError, "probe_scene: the scene has no camera (call set_camera)");
    if (scene.dirty()) scene.commit();
    ProbeResult r;
    {
        nb::gil_scoped_release release;
        r = probe_scene(scene, o);
    }
    nb::dict d;
    d["light_paths"] = r.light_paths;
    d["light_hit_specular"] = r.light_hit_specular;
    d["light_caustics"] = r.light_caustics;
    d["direct_flux"] = r.direct_flux;
    d["caustic_flux_emitted"] = r.caustic_flux_emitted;
    d["candidate_area"] = r.candidate_area;
    d["targeted_paths"] = r.targeted_paths;
    d["targeted_reached"] = r.targeted_reached;
    d["targeted_caustics"] = r.targeted_caustics;
    d["caustic_flux_targeted"] = r.caustic_flux_targeted;
    d["camera_paths"] = r.camera_paths;
    d["camera_diffuse_hits"] = r.camera_diffuse_hits;
    d["camera_specular_first"] = r.camera_specular_first;
    d["camera_escaped"] = r.camera_escaped;
    d["direct_visible"] = r.direct_visible;
    d["bounce_visible"] = r.bounce_visible;
    d["lit_hits"] = r.lit_hits;
    d["direct_irradiance"] = r.direct_irradiance;
    d["indirect_irradiance"] = r.indirect_irradiance;
    d["indirect_rel_var"] = r.indirect_rel_var;
    return d;
}

std::vector<bool> lambert_kernel_py(const Scene& scene) {
    std::vector<bool> out(scene.material_count());
    for (size_t i = 0; i < out.size(); ++i) out[i] = exact_lambertian(scene.material(uint32_t(i)));
    return out;
}

nb::dict scene_memory_py(const Scene& scene) {
    if (scene.dirty())
        throw SceneError("scene_memory: the scene changed since the last commit(); call commit()");
    const SceneMemory m = scene_memory(scene);
    nb::dict d;
    d["meshes"] = m.meshes;
    d["instances"] = m.instances;
    d["triangles"] = m.triangles;
    d["vertices"] = m.vertices;
    d["bvh_bytes"] = m.bvh_bytes;
    d["top_level_bytes"] = m.top_level_bytes;
    d["point_bytes"] = m.point_bytes;
    d["index_bytes"] = m.index_bytes;
    d["normal_bytes"] = m.normal_bytes;
    d["uv_bytes"] = m.uv_bytes;
    d["material_id_bytes"] = m.material_id_bytes;
    d["primvar_bytes"] = m.primvar_bytes;
    d["light_map_bytes"] = m.light_map_bytes;
    d["placed_point_bytes"] = m.placed_point_bytes;
    d["mesh_bytes"] = m.mesh_bytes();
    d["total_bytes"] = m.total_bytes();
    d["bytes_per_triangle"] = m.bytes_per_triangle();
    return d;
}

}  // namespace

void bind_analysis(nb::module_& m) {
    m.def("probe_scene", &probe_py, "scene"_a, "width"_a, "height"_a, "seed"_a = 0,
          "light_paths"_a = 1024, "targeted_paths"_a = 1024, "camera_paths"_a = 256,
          "light_samples"_a = 4, "max_chain"_a = 8, "specular_roughness"_a = 0.2f,
          "Probe paths for the scene analysis (analysis/scene_probes.h): caustic paths L S+ D "
          "the camera sees (counts and flux estimates) and how often light samples at the "
          "camera's first diffuse hits and one bounce further reach a light. A dict.");
    m.def("lambert_kernel_materials", &lambert_kernel_py, "scene"_a,
          "Per material of the scene: whether RenderSettings.kernel = 'auto' renders it with "
          "the diffuse-only kernel (an exact Lambertian, analysis/kernel_select.h).");
    m.def("scene_memory", &scene_memory_py, "scene"_a,
          "What the committed scene's geometry takes (scene/scene_memory.h): Embree's BVHs "
          "(bvh_bytes, its memory monitor) and the mesh arrays the core reads (points, "
          "indices, normals, uvs, material ids, primvars, light map), in bytes, with "
          "triangles (of the meshes, an instanced mesh once) and bytes_per_triangle.");
}

}  // namespace cmlt::bindings
