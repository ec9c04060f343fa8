// Bindings of cmlt::Scene: zero-copy meshes, instances, materials, lights, camera.
#include "bind_common.h"

#include "scene/scene.h"
#include "util/error.h"

#include <nanobind/stl/array.h>
#include <nanobind/stl/string.h>

#include <cmath>

namespace cmlt::bindings {

using namespace nb::literals;

namespace {

uint32_t add_mesh(Scene& s, const std::string& name, nb::handle points, nb::handle indices,
                  nb::handle normals, nb::handle uvs, nb::handle material_ids,
                  nb::handle primvars) {
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
        if (ma.ndim() == 1 && ma.shape(0) == 1 && d.n_tris != 1) {
            // one id for the whole mesh: no per-triangle array
            d.material_id_all = checked_matrix<uint32_t>(ma, fn, "material_ids", 1, 0, "uint32")[0];
        } else {
            d.material_ids =
                checked_matrix<uint32_t>(ma, fn, "material_ids", long(d.n_tris), 0, "uint32");
            keep.push_back(nb::borrow(material_ids));
        }
    }
    if (!primvars.is_none()) {
        AnyArray va = as_array(primvars, fn, "primvars");
        if (va.ndim() != 2 || va.shape(1) < 1 || va.shape(1) > size_t(k_max_primvar_columns))
            throw nb::value_error(("add_mesh: primvars must have shape (N, K) with K in 1.." +
                                   std::to_string(k_max_primvar_columns))
                                      .c_str());
        d.primvars = checked_matrix<float>(va, fn, "primvars", long(d.n_points), long(va.shape(1)),
                                           "float32");
        d.n_primvar_columns = uint32_t(va.shape(1));
        keep.push_back(nb::borrow(primvars));
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

/// Fill the UsdPreviewSurface fields of `m` from row `r` of the params table (float32 (K, P)).
void material_from_params(Material& m, const float* row, size_t cols, size_t r) {
    namespace c = material_col;
    auto tex = [&](int col, const char* what) -> int32_t {
        if (size_t(col) >= cols) return -1;
        float v = row[col];
        if (!(v >= -1.f) || !std::isfinite(v) || v != std::floor(v))
            throw nb::value_error(("set_materials: params[" + std::to_string(r) + ", " +
                                   std::to_string(col) + "] (" + what +
                                   " texture id) must be -1 or a texture id, got " +
                                   std::to_string(v))
                                      .c_str());
        return int32_t(v);
    };
    auto ch = [&](int col, uint8_t def) -> uint8_t {
        if (size_t(col) >= cols) return def;
        float v = row[col];
        if (!(v >= 0.f && v <= 3.f) || v != std::floor(v))
            throw nb::value_error(("set_materials: params[" + std::to_string(r) + ", " +
                                   std::to_string(col) + "] (texture channel) must be 0..3")
                                      .c_str());
        return uint8_t(v);
    };
    m.preview = true;
    m.specular = Spectrum(row[c::specular_r], row[c::specular_g], row[c::specular_b]);
    m.use_specular_workflow = row[c::use_specular_workflow] != 0.f;
    m.metallic = row[c::metallic];
    m.roughness = row[c::roughness];
    m.clearcoat = row[c::clearcoat];
    m.clearcoat_roughness = row[c::clearcoat_roughness];
    m.opacity = row[c::opacity];
    m.opacity_threshold = row[c::opacity_threshold];
    m.ior = row[c::ior];
    for (int col = 0; col < k_param_cols_basic; ++col)
        if (!std::isfinite(row[col]))
            throw nb::value_error(("set_materials: params[" + std::to_string(r) + ", " +
                                   std::to_string(col) + "] is NaN or Inf")
                                      .c_str());
    m.tex_diffuse = tex(c::tex_diffuse, "diffuseColor");
    m.tex_emission = tex(c::tex_emission, "emissiveColor");
    m.tex_specular = tex(c::tex_specular, "specularColor");
    m.tex_normal = tex(c::tex_normal, "normal");
    m.tex_metallic = tex(c::tex_metallic, "metallic");
    m.tex_roughness = tex(c::tex_roughness, "roughness");
    m.tex_clearcoat = tex(c::tex_clearcoat, "clearcoat");
    m.tex_clearcoat_roughness = tex(c::tex_clearcoat_roughness, "clearcoatRoughness");
    m.tex_opacity = tex(c::tex_opacity, "opacity");
    m.ch_metallic = ch(c::ch_metallic, 0);
    m.ch_roughness = ch(c::ch_roughness, 0);
    m.ch_clearcoat = ch(c::ch_clearcoat, 0);
    m.ch_clearcoat_roughness = ch(c::ch_clearcoat_roughness, 0);
    m.ch_opacity = ch(c::ch_opacity, 3);
    auto pv = [&](int col, const char* what) -> int8_t {
        if (size_t(col) >= cols) return -1;
        float v = row[col];
        if (!(v >= -1.f && v < float(k_max_primvar_columns)) || v != std::floor(v))
            throw nb::value_error(("set_materials: params[" + std::to_string(r) + ", " +
                                   std::to_string(col) + "] (" + what +
                                   " primvar column) must be -1 or 0.." +
                                   std::to_string(k_max_primvar_columns - 1) + ", got " +
                                   std::to_string(v))
                                      .c_str());
        return int8_t(v);
    };
    m.pv_diffuse = pv(c::pv_diffuse, "diffuseColor");
    m.pv_specular = pv(c::pv_specular, "specularColor");
    m.pv_metallic = pv(c::pv_metallic, "metallic");
    m.pv_roughness = pv(c::pv_roughness, "roughness");
    m.pv_clearcoat = pv(c::pv_clearcoat, "clearcoat");
    m.pv_clearcoat_roughness = pv(c::pv_clearcoat_roughness, "clearcoatRoughness");
    m.pv_opacity = pv(c::pv_opacity, "opacity");
}

void set_materials(Scene& s, nb::handle diffuse, nb::handle emission, nb::handle params) {
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
    if (!params.is_none()) {
        AnyArray pa = as_array(params, "set_materials", "params");
        if (pa.ndim() != 2 || (pa.shape(1) != size_t(k_param_cols_basic) &&
                               pa.shape(1) != size_t(k_param_cols_full) &&
                               pa.shape(1) != size_t(k_param_cols_primvar)))
            throw nb::value_error(("set_materials: params must have shape (K, " +
                                   std::to_string(k_param_cols_basic) + "), (K, " +
                                   std::to_string(k_param_cols_full) + ") or (K, " +
                                   std::to_string(k_param_cols_primvar) + ")")
                                      .c_str());
        const float* p = checked_matrix<float>(pa, "set_materials", "params", long(d.size()),
                                               long(pa.shape(1)), "float32");
        for (size_t i = 0; i < d.size(); ++i)
            material_from_params(mats[i], p + i * pa.shape(1), pa.shape(1), i);
    }
    s.set_materials(std::move(mats));
}

WrapMode wrap_mode(const std::string& w, const char* arg) {
    if (w == "repeat" || w.empty()) return WrapMode::repeat;
    // useMetadata without the file's metadata (the Python side reads it): black, as the
    // UsdPreviewSurface spec says
    if (w == "useMetadata") return WrapMode::black;
    if (w == "mirror") return WrapMode::mirror;
    if (w == "clamp") return WrapMode::clamp;
    if (w == "black") return WrapMode::black;
    throw nb::value_error((std::string("add_texture: ") + arg +
                           " must be repeat, mirror, clamp, black or useMetadata, got '" + w + "'")
                              .c_str());
}

uint32_t add_texture(Scene& s, nb::handle image, const std::string& wrap_s,
                     const std::string& wrap_t, const std::array<float, 4>& scale,
                     const std::array<float, 4>& bias, const std::string& name,
                     const std::array<float, 6>& st_transform) {
    AnyArray a = as_array(image, "add_texture", "image");
    if (a.dtype() != nb::dtype<float>())
        throw nb::type_error(("add_texture: image must have dtype float32, got " +
                              dtype_name(a.dtype()))
                                 .c_str());
    if (a.ndim() != 3 || a.shape(2) < 1 || a.shape(2) > 4 || a.shape(0) < 1 || a.shape(1) < 1)
        throw nb::value_error("add_texture: image must have shape (H, W, C) with C in 1..4");
    int64_t c = int64_t(a.shape(2)), w = int64_t(a.shape(1));
    if (a.stride(2) != 1 || a.stride(1) != c || a.stride(0) != w * c)
        throw nb::value_error("add_texture: image must be C-contiguous (np.ascontiguousarray)");
    TextureDesc d;
    d.data = static_cast<const float*>(a.data());
    d.height = int(a.shape(0));
    d.width = int(a.shape(1));
    d.channels = int(a.shape(2));
    d.wrap_s = wrap_mode(wrap_s, "wrap_s");
    d.wrap_t = wrap_mode(wrap_t, "wrap_t");
    d.scale = Vec4(scale[0], scale[1], scale[2], scale[3]);
    d.bias = Vec4(bias[0], bias[1], bias[2], bias[3]);
    for (int i = 0; i < 6; ++i) d.st_transform[i] = st_transform[size_t(i)];
    d.owner = make_owner({nb::borrow(image)});
    return s.add_texture(std::move(d), name);
}

uint32_t add_light(Scene& s, const std::string& kind, nb::handle transform,
                   const std::array<float, 3>& radiance, float width, float height, float radius,
                   float length, float angle, bool treat_as_point, int32_t texture_id,
                   float cone_angle, float cone_softness, float focus,
                   const std::array<float, 3>& focus_tint) {
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
    d.texture_id = texture_id;
    d.cone_angle = cone_angle;
    d.cone_softness = cone_softness;
    d.focus = focus;
    d.focus_tint = Spectrum(focus_tint[0], focus_tint[1], focus_tint[2]);
    return s.add_light(d);
}

void set_camera(Scene& s, nb::handle transform, float focal_length, float ha, float va, float hoff,
                float voff, float near_, float far_, float f_stop, float focus_distance,
                const std::string& projection, float lens_unit) {
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
    d.lens_unit = lens_unit;
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
             "uvs"_a = nb::none(), "material_ids"_a = nb::none(), "primvars"_a = nb::none(),
             "Add a mesh without copying: points float32 (N,3) from padded_points, indices uint32 "
             "(M,3), normals float32 (N,3), uvs float32 (N,2), material_ids uint32 (M,) (or (1,): one "
             "material for every triangle), primvars "
             "float32 (N,K) per-vertex primvar columns (K <= 8) that material inputs driven by a "
             "UsdPrimvarReader read (set_materials params columns 25-31). The arrays "
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
        .def(
            "set_instance_motion",
            [](Scene& s, uint32_t id, nb::sequence steps) {
                std::vector<Mat4> mats;
                for (nb::handle h : steps)
                    mats.push_back(to_mat4(h, "set_instance_motion", "steps[k]"));
                s.set_instance_motion(id, mats);
            },
            "instance_id"_a, "steps"_a,
            "Motion blur: a sequence of >= 2 float64 (4,4) object->world transforms evenly\n"
            "spaced over the shutter (ray time 0..1); one step = set_instance_transform.")
        .def_prop_ro("motion_blur", &Scene::motion_blur,
                     "Some instance carries shutter time steps (a ray time is then sampled).")
        .def_prop_ro("has_pass_through", &Scene::has_pass_through,
                     "Some material can let rays through without scattering (opacityThreshold\n"
                     "cut-outs, ior-1 surfaces with opacity < 1); shadow rays then step through\n"
                     "such surfaces (known after commit()).")
        .def("set_materials", &set_materials, "diffuse"_a, "emission"_a, "params"_a = nb::none(),
             "Material table: diffuse and emission (K,3); material_ids index the rows.\n\n"
             "params=None: Lambert materials (diffuse + emission only). Otherwise every row is a\n"
             "UsdPreviewSurface; params is float32 (K, 11), (K, 25) or (K, 32) with columns\n"
             "  0-2 specularColor rgb, 3 useSpecularWorkflow (0/1), 4 metallic, 5 roughness,\n"
             "  6 clearcoat, 7 clearcoatRoughness, 8 opacity, 9 opacityThreshold, 10 ior,\n"
             "  texture ids (-1 = none): 11 diffuseColor, 12 emissiveColor, 13 specularColor,\n"
             "  14 normal, 15 metallic, 16 roughness, 17 clearcoat, 18 clearcoatRoughness,\n"
             "  19 opacity; channels (0..3 = r,g,b,a) read by the scalar inputs: 20 metallic,\n"
             "  21 roughness, 22 clearcoat, 23 clearcoatRoughness, 24 opacity; first primvar\n"
             "  column (-1 = none; colours read 3 columns) of the mesh's primvars: 25 diffuseColor,\n"
             "  26 specularColor, 27 metallic, 28 roughness, 29 clearcoat, 30 clearcoatRoughness,\n"
             "  31 opacity.\n"
             "(cmlt.shot.material_table.MATERIAL_PARAM_COLUMNS mirrors this layout.)")
        .def("add_texture", &add_texture, "image"_a, "wrap_s"_a = "repeat", "wrap_t"_a = "repeat",
             "scale"_a = std::array<float, 4>{1.f, 1.f, 1.f, 1.f},
             "bias"_a = std::array<float, 4>{0.f, 0.f, 0.f, 0.f}, "name"_a = "texture",
             "st_transform"_a = std::array<float, 6>{1.f, 0.f, 0.f, 0.f, 1.f, 0.f},
             "Register a float32 (H, W, C) image (C-contiguous, row 0 = top, already in the\n"
             "rendering space or raw) without copying, with the UsdUVTexture sampler state\n"
             "(wrap repeat|mirror|clamp|black, per-channel scale and bias) and the affine\n"
             "st_transform (a, b, tx, c, d, ty): st' = (a s + b t + tx, c s + d t + ty),\n"
             "applied before the lookup (UsdTransform2d). Returns its id.")
        .def_prop_ro("texture_count", &Scene::texture_count)
        .def("clear_lights", &Scene::clear_lights)
        .def("add_light", &add_light, "kind"_a, "transform"_a, "radiance"_a, "width"_a = 1.0f,
             "height"_a = 1.0f, "radius"_a = 0.5f, "length"_a = 1.0f, "angle"_a = 0.53f,
             "treat_as_point"_a = false, "texture_id"_a = -1, "cone_angle"_a = 180.0f,
             "cone_softness"_a = 0.0f, "focus"_a = 0.0f,
             "focus_tint"_a = std::array<float, 3>{0.f, 0.f, 0.f},
             "Add a UsdLux light: kind rect|disk|sphere|distant|dome|cylinder (cylinder: the\n"
             "side along local X emits outward; treat_as_point = treatAsLine is ignored).\n"
             "radiance = intensity * 2^exposure * color (/ area if normalize).\n"
             "cone_angle (degrees, half-angle about -Z), cone_softness, focus, focus_tint:\n"
             "UsdLux ShapingAPI for rect, disk, sphere, cylinder (lights/shaping.h).\n"
             "texture_id (add_texture, registered before): dome = lat-long HDR environment\n"
             "(UsdLux/OpenEXR latlong, +Y pole, importance sampled), rect = inputs:texture:file;\n"
             "the radiance is multiplied by the texture's rgb.")
        .def("set_camera", &set_camera, "transform"_a, "focal_length"_a, "horizontal_aperture"_a,
             "vertical_aperture"_a, "horizontal_aperture_offset"_a = 0.0f,
             "vertical_aperture_offset"_a = 0.0f, "near"_a = 0.01f, "far"_a = 1e6f,
             "f_stop"_a = 0.0f, "focus_distance"_a = 0.0f, "projection"_a = "perspective",
             "lens_unit"_a = 0.001f,
             "Camera (looks down local -Z). Thin-lens depth of field when f_stop > 0 and\n"
             "focus_distance > 0 (metres): lens radius = focal_length * lens_unit / (2 f_stop)\n"
             "metres, lens_unit = metres per focal-length unit (0.001: mm).")
        .def("commit", &Scene::commit, "Build/refit BVHs and the light list.")
        .def_prop_ro("mesh_count", &Scene::mesh_count)
        .def_prop_ro("instance_count", &Scene::instance_count)
        .def_prop_ro("light_count", [](const Scene& s) { return s.light_count(); },
                     "Lights after the last commit (analytic + emissive triangles).");
}

}  // namespace cmlt::bindings
