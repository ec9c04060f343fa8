// Bindings of cmlt::Scene: zero-copy meshes, instances, materials, lights, camera.
#include "bind_common.h"

#include "scene/scene.h"
#include "util/error.h"

#include <nanobind/stl/array.h>
#include <nanobind/stl/string.h>

namespace cmlt::bindings {

using namespace nb::literals;

namespace {

uint32_t add_mesh(Scene& s, const std::string& name, nb::handle points, nb::handle indices,
                  nb::handle normals, nb::handle uvs, nb::handle material_ids) {
    const char* fn = "add_mesh";
    std::vector<nb::object> keep;
    MeshData d;
    AnyArray pa = as_array(points, fn, "points");
    d.points = checked_matrix<float>(pa, fn, "points", -1, 3, "float32");
    d.n_points = pa.shape(0);
    keep.push_back(nb::borrow(points));
    AnyArray ia = as_array(indices, fn, "indices");
    d.indices = checked_matrix<uint32_t>(ia, fn, "indices", -1, 3, "uint32");
    d.n_tris = ia.shape(0);
    keep.push_back(nb::borrow(indices));
    if (!normals.is_none()) {
        AnyArray na = as_array(normals, fn, "normals");
        d.normals = checked_matrix<float>(na, fn, "normals", long(d.n_points), 3, "float32");
        keep.push_back(nb::borrow(normals));
    }
    if (!uvs.is_none()) {
        AnyArray ua = as_array(uvs, fn, "uvs");
        d.uvs = checked_matrix<float>(ua, fn, "uvs", long(d.n_points), 2, "float32");
        keep.push_back(nb::borrow(uvs));
    }
    if (!material_ids.is_none()) {
        AnyArray ma = as_array(material_ids, fn, "material_ids");
        d.material_ids = checked_matrix<uint32_t>(ma, fn, "material_ids", long(d.n_tris), 0, "uint32");
        keep.push_back(nb::borrow(material_ids));
    }
    d.owner = make_owner(std::move(keep));
    return s.add_mesh(name, std::move(d));
}

void update_mesh_points(Scene& s, uint32_t mesh_id, nb::handle points, nb::handle normals) {
    const char* fn = "update_mesh_points";
    if (mesh_id >= s.mesh_count())
        throw SceneError("update_mesh_points: mesh_id " + std::to_string(mesh_id) +
                         " out of range (have " + std::to_string(s.mesh_count()) + " meshes)");
    long n = long(s.mesh(mesh_id).data.n_points);
    std::vector<nb::object> keep;
    AnyArray pa = as_array(points, fn, "points");
    const float* p = checked_matrix<float>(pa, fn, "points", -1, 3, "float32");
    keep.push_back(nb::borrow(points));
    const float* nrm = nullptr;
    if (!normals.is_none()) {
        AnyArray na = as_array(normals, fn, "normals");
        nrm = checked_matrix<float>(na, fn, "normals", n, 3, "float32");
        keep.push_back(nb::borrow(normals));
    }
    s.update_mesh_points(mesh_id, p, pa.shape(0), nrm, make_owner(std::move(keep)));
}

std::vector<Spectrum> rows3(nb::handle obj, const char* fn, const char* arg) {
    AnyArray a = as_array(obj, fn, arg);
    bool f64 = a.dtype() == nb::dtype<double>(), f32 = a.dtype() == nb::dtype<float>();
    if (!f64 && !f32)
        throw nb::type_error((std::string(fn) + ": " + arg + " must be float32 or float64 (K, 3), got " +
                              dtype_name(a.dtype()))
                                 .c_str());
    if (a.ndim() != 2 || a.shape(1) != 3)
        throw nb::value_error((std::string(fn) + ": " + arg + " must have shape (K, 3)").c_str());
    std::vector<Spectrum> out(a.shape(0));
    for (size_t r = 0; r < a.shape(0); ++r)
        for (int c = 0; c < 3; ++c) {
            int64_t off = int64_t(r) * a.stride(0) + c * a.stride(1);
            out[r][c] = f64 ? float(static_cast<const double*>(a.data())[off])
                            : static_cast<const float*>(a.data())[off];
        }
    return out;
}

void set_materials(Scene& s, nb::handle diffuse, nb::handle emission) {
    auto d = rows3(diffuse, "set_materials", "diffuse");
    auto e = rows3(emission, "set_materials", "emission");
    if (d.size() != e.size())
        throw nb::value_error(("set_materials: diffuse has " + std::to_string(d.size()) +
                               " rows but emission has " + std::to_string(e.size()))
                                  .c_str());
    std::vector<Material> mats(d.size());
    for (size_t i = 0; i < d.size(); ++i) {
        mats[i].diffuse = d[i];
        mats[i].emission = e[i];
    }
    s.set_materials(std::move(mats));
}

uint32_t add_light(Scene& s, const std::string& kind, nb::handle transform,
                   const std::array<float, 3>& radiance, float width, float height, float radius,
                   float length, float angle, bool treat_as_point) {
    LightDesc d;
    if (kind == "rect") d.kind = LightDesc::Kind::rect;
    else if (kind == "disk") d.kind = LightDesc::Kind::disk;
    else if (kind == "sphere") d.kind = LightDesc::Kind::sphere;
    else if (kind == "distant") d.kind = LightDesc::Kind::distant;
    else if (kind == "dome") d.kind = LightDesc::Kind::dome;
    else if (kind == "cylinder") d.kind = LightDesc::Kind::cylinder;
    else
        throw SceneError("add_light: unknown kind '" + kind +
                         "' (expected rect, disk, sphere, distant, dome or cylinder)");
    d.transform = to_mat4(transform, "add_light", "transform");
    d.radiance = Spectrum(radiance[0], radiance[1], radiance[2]);
    d.width = width;
    d.height = height;
    d.radius = radius;
    d.length = length;
    d.angle = angle;
    d.treat_as_point = treat_as_point;
    return s.add_light(d);
}

void set_camera(Scene& s, nb::handle transform, float focal_length, float ha, float va, float hoff,
                float voff, float near_, float far_, float f_stop, float focus_distance,
                const std::string& projection) {
    CameraDesc d;
    d.transform = to_mat4(transform, "set_camera", "transform");
    d.focal_length = focal_length;
    d.horizontal_aperture = ha;
    d.vertical_aperture = va;
    d.horizontal_aperture_offset = hoff;
    d.vertical_aperture_offset = voff;
    d.near = near_;
    d.far = far_;
    d.f_stop = f_stop;
    d.focus_distance = focus_distance;
    if (projection == "perspective") d.projection = CameraDesc::Projection::perspective;
    else if (projection == "orthographic") d.projection = CameraDesc::Projection::orthographic;
    else
        throw SceneError("set_camera: projection must be 'perspective' or 'orthographic', got '" +
                         projection + "'");
    s.set_camera(d);
}

}  // namespace

void bind_scene(nb::module_& m) {
    nb::class_<Scene>(m, "Scene", "The render scene of one frame (meshes share numpy memory).")
        .def(nb::init<>())
        .def("add_mesh", &add_mesh, "name"_a, "points"_a, "indices"_a, "normals"_a = nb::none(),
             "uvs"_a = nb::none(), "material_ids"_a = nb::none(),
             "Add a mesh without copying: points float32 (N,3) from padded_points, indices uint32 "
             "(M,3), normals float32 (N,3), uvs float32 (N,2), material_ids uint32 (M,). The arrays "
             "are kept alive and must not be modified afterwards. Returns the mesh id.")
        .def("update_mesh_points", &update_mesh_points, "mesh_id"_a, "points"_a,
             "normals"_a = nb::none(),
             "Replace a mesh's points (same count; zero copy) and optionally its normals.")
        .def(
            "add_instance",
            [](Scene& s, uint32_t mesh_id, nb::handle xf) {
                return s.add_instance(mesh_id, to_mat4(xf, "add_instance", "transform"));
            },
            "mesh_id"_a, "transform"_a, "Place a mesh; transform float64 (4,4) object->world.")
        .def(
            "set_instance_transform",
            [](Scene& s, uint32_t id, nb::handle xf) {
                s.set_instance_transform(id, to_mat4(xf, "set_instance_transform", "transform"));
            },
            "instance_id"_a, "transform"_a)
        .def("set_materials", &set_materials, "diffuse"_a, "emission"_a,
             "Material table: diffuse and emission (K,3); material_ids index the rows.")
        .def("clear_lights", &Scene::clear_lights)
        .def("add_light", &add_light, "kind"_a, "transform"_a, "radiance"_a, "width"_a = 1.0f,
             "height"_a = 1.0f, "radius"_a = 0.5f, "length"_a = 1.0f, "angle"_a = 0.53f,
             "treat_as_point"_a = false,
             "Add a UsdLux light: kind rect|disk|sphere|distant|dome (cylinder: not supported "
             "yet). radiance = intensity * 2^exposure * color (/ area if normalize).")
        .def("set_camera", &set_camera, "transform"_a, "focal_length"_a, "horizontal_aperture"_a,
             "vertical_aperture"_a, "horizontal_aperture_offset"_a = 0.0f,
             "vertical_aperture_offset"_a = 0.0f, "near"_a = 0.01f, "far"_a = 1e6f,
             "f_stop"_a = 0.0f, "focus_distance"_a = 0.0f, "projection"_a = "perspective")
        .def("commit", &Scene::commit, "Build/refit BVHs and the light list.")
        .def_prop_ro("mesh_count", &Scene::mesh_count)
        .def_prop_ro("instance_count", &Scene::instance_count)
        .def_prop_ro("light_count", [](const Scene& s) { return s.light_count(); },
                     "Lights after the last commit (analytic + emissive triangles).");
}

}  // namespace cmlt::bindings
