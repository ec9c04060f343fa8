#include "scene/scene.h"

#include "analysis/kernel_select.h"

#include "scene/coordinate_range.h"

#include "lights/area_lights.h"
#include "lights/cylinder_light.h"
#include "lights/infinite_lights.h"
#include "lights/sphere_light.h"
#include "materials/material_eval.h"
#include "util/error.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace cmlt {

Scene::Scene() : m_accel(new Accel()) { m_materials.push_back(Material()); }
Scene::~Scene() = default;

namespace {

void validate_finite(const std::string& name, const char* array, const float* data, size_t rows,
                     size_t cols) {
    for (size_t i = 0; i < rows * cols; ++i) {
        if (!std::isfinite(data[i]))
            CMLT_THROW(SceneError, "mesh '" << name << "': " << array << "[" << i / cols << "] has a "
                                             << "NaN or Inf component (" << data[i] << ")");
    }
}

void point_bounds(const float* p, size_t n, Vec3* lo, Vec3* hi) {
    *lo = Vec3(k_infinity);
    *hi = Vec3(-k_infinity);
    for (size_t i = 0; i < n; ++i) {
        Vec3 v(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
        *lo = vmin(*lo, v);
        *hi = vmax(*hi, v);
    }
}

}  // namespace

uint32_t Scene::add_mesh(const std::string& name, MeshData data) {
    // Validate at the boundary, naming the mesh.
    if (!data.points && data.n_points > 0) CMLT_THROW(SceneError, "mesh '" << name << "': points is null");
    if (!data.indices && data.n_tris > 0) CMLT_THROW(SceneError, "mesh '" << name << "': indices is null");
    if (data.n_points > 0xFFFFFFFFull || data.n_tris > 0xFFFFFFFFull)
        CMLT_THROW(SceneError, "mesh '" << name << "': more than 2^32 points or triangles");
    validate_finite(name, "points", data.points, data.n_points, 3);
    for (size_t i = 0; i < data.n_tris * 3; ++i) {
        if (data.indices[i] >= data.n_points)
            CMLT_THROW(SceneError, "mesh '" << name << "': indices[" << i / 3 << "] refers to point "
                                            << data.indices[i] << " but points has " << data.n_points
                                            << " entries");
    }
    if (data.normals) validate_finite(name, "normals", data.normals, data.n_points, 3);
    if (data.uvs) validate_finite(name, "uvs", data.uvs, data.n_points, 2);
    if (data.n_primvar_columns > uint32_t(k_max_primvar_columns))
        CMLT_THROW(SceneError, "mesh '" << name << "': " << data.n_primvar_columns
                                        << " primvar columns, at most " << k_max_primvar_columns);
    if (data.n_primvar_columns > 0 && !data.primvars)
        CMLT_THROW(SceneError, "mesh '" << name << "': primvars is null");
    if (!data.primvars) data.n_primvar_columns = 0;
    if (data.primvars)
        validate_finite(name, "primvars", data.primvars, data.n_points, data.n_primvar_columns);

    Mesh mesh;
    mesh.name = name;
    point_bounds(data.points, data.n_points, &mesh.bbox_min, &mesh.bbox_max);
    mesh.data = std::move(data);
    uint32_t id = m_accel->add_mesh(mesh.data.points, mesh.data.n_points, mesh.data.indices,
                                    mesh.data.n_tris);
    CMLT_CHECK(id == m_meshes.size());
    m_meshes.push_back(std::move(mesh));
    m_point_owners.emplace_back();
    m_dirty = true;
    return id;
}

void Scene::update_mesh_points(uint32_t mesh_id, const float* points, size_t n_points,
                               const float* normals, std::shared_ptr<void> owner) {
    if (mesh_id >= m_meshes.size())
        CMLT_THROW(SceneError, "update_mesh_points: mesh id " << mesh_id << " out of range (have "
                                                              << m_meshes.size() << " meshes)");
    Mesh& mesh = m_meshes[mesh_id];
    if (n_points != mesh.data.n_points)
        CMLT_THROW(SceneError, "mesh '" << mesh.name << "': update_mesh_points got " << n_points
                                        << " points but the mesh has " << mesh.data.n_points
                                        << " (topology changes need a new mesh)");
    validate_finite(mesh.name, "points", points, n_points, 3);
    if (normals) validate_finite(mesh.name, "normals", normals, n_points, 3);
    mesh.data.points = points;
    if (normals) mesh.data.normals = normals;
    point_bounds(points, n_points, &mesh.bbox_min, &mesh.bbox_max);
    m_point_owners[mesh_id] = std::move(owner);
    m_accel->update_mesh_points(mesh_id, points);
    for (size_t i = 0; i < m_instances.size(); ++i)
        if (m_instances[i].mesh_id == mesh_id) m_placed_stale[i] = 1;
    m_dirty = true;
}

uint32_t Scene::add_instance(uint32_t mesh_id, const Mat4& object_to_world) {
    if (mesh_id >= m_meshes.size())
        CMLT_THROW(SceneError, "add_instance: mesh id " << mesh_id << " out of range (have "
                                                        << m_meshes.size() << " meshes)");
    std::string what = "instance of mesh '" + m_meshes[mesh_id].name + "'";
    Instance inst;
    inst.mesh_id = mesh_id;
    inst.xf = Transform(object_to_world, what.c_str());
    uint32_t id = m_accel->add_instance(mesh_id, object_to_world);
    CMLT_CHECK(id == m_instances.size());
    m_instances.push_back(inst);
    m_placed.emplace_back();
    m_placed_stale.push_back(1);
    m_dirty = true;
    return id;
}

void Scene::set_instance_transform(uint32_t instance_id, const Mat4& object_to_world) {
    if (instance_id >= m_instances.size())
        CMLT_THROW(SceneError, "set_instance_transform: instance id " << instance_id
                                   << " out of range (have " << m_instances.size() << " instances)");
    Instance& inst = m_instances[instance_id];
    std::string what = "instance " + std::to_string(instance_id) + " of mesh '" +
                       m_meshes[inst.mesh_id].name + "'";
    inst.xf = Transform(object_to_world, what.c_str());
    inst.motion.clear();
    m_placed_stale[instance_id] = 1;
    m_accel->set_instance_transform(instance_id, object_to_world);
    m_dirty = true;
}

Mat4 Instance::matrix_at(float time) const {
    if (motion.size() < 2) return xf.m;
    float x = std::min(std::max(time, 0.f), 1.f) * float(motion.size() - 1);
    size_t k = std::min(size_t(x), motion.size() - 2);
    double f = double(x) - double(k);
    Mat4 out;
    for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c)
            out.m[r][c] = (1.0 - f) * motion[k].m[r][c] + f * motion[k + 1].m[r][c];
    return out;
}

void Scene::set_instance_motion(uint32_t instance_id, const std::vector<Mat4>& steps) {
    if (instance_id >= m_instances.size())
        CMLT_THROW(SceneError, "set_instance_motion: instance id " << instance_id
                                   << " out of range (have " << m_instances.size() << " instances)");
    if (steps.empty() || steps.size() > 129)
        CMLT_THROW(SceneError, "set_instance_motion: need 1 to 129 time steps, got " << steps.size());
    if (steps.size() == 1) {
        set_instance_transform(instance_id, steps[0]);
        return;
    }
    Instance& inst = m_instances[instance_id];
    std::string what = "instance " + std::to_string(instance_id) + " of mesh '" +
                       m_meshes[inst.mesh_id].name + "' (motion step)";
    for (const Mat4& m : steps) Transform(m, what.c_str());  // validates every step
    inst.xf = Transform(steps[0], what.c_str());
    inst.motion = steps;
    m_placed_stale[instance_id] = 1;
    m_accel->set_instance_motion(instance_id, steps.data(), uint32_t(steps.size()));
    m_dirty = true;
}

bool Scene::motion_blur() const {
    for (const Instance& inst : m_instances)
        if (inst.motion.size() > 1) return true;
    return false;
}

void Scene::set_materials(std::vector<Material> materials) {
    if (materials.empty()) CMLT_THROW(SceneError, "set_materials: need at least one material (K >= 1)");
    for (size_t i = 0; i < materials.size(); ++i) {
        const Material& m = materials[i];
        if (!is_finite(m.diffuse) || min_component(m.diffuse) < 0.f)
            CMLT_THROW(SceneError, "set_materials: diffuse[" << i << "] must be finite and >= 0");
        if (!is_finite(m.emission) || min_component(m.emission) < 0.f)
            CMLT_THROW(SceneError, "set_materials: emission[" << i << "] must be finite and >= 0");
    }
    m_materials = std::move(materials);
    select_kernels(false);
    m_dirty = true;
}

int Scene::select_kernels(bool general) {
    int n = 0;
    for (Material& m : m_materials) {
        m.lambert_kernel = !general && exact_lambertian(m);
        prepare_constant_bsdf(&m);
        n += m.lambert_kernel ? 1 : 0;
    }
    classify_constant_lambert();
    return n;
}

void Scene::classify_constant_lambert() {
    const size_t n = m_materials.size();
    m_constant_lambert.assign(n, 0);
    m_lambert_r.assign(n, Spectrum(0.f));
    m_constant_preview.assign(n, nullptr);
    m_lane_material.assign(n, 0);
    for (size_t i = 0; i < n; ++i) {
        if (i < m_material_passes.size() && m_material_passes[i]) continue;
        const Material& m = m_materials[i];
        m_constant_lambert[i] = cmlt::constant_lambert(m, m_textures, &m_lambert_r[i]) ? 1 : 0;
        if (m_constant_lambert[i] || m.tex_normal >= 0 || m.is_emissive()) continue;
        // make_bsdf's constant preview case (Material::constant_bsdf) without a normal map
        if (m.preview && !m.lambert_kernel && m.constant_bsdf)
            m_constant_preview[i] = &*m.constant_bsdf;
        else
            m_lane_material[i] = 1;
    }
}

uint32_t Scene::add_texture(TextureDesc desc, const std::string& name) {
    std::string what = "texture '" + name + "'";
    m_textures.emplace_back(std::move(desc), what.c_str());
    m_dirty = true;
    return uint32_t(m_textures.size() - 1);
}

void Scene::clear_lights() {
    m_analytic.clear();
    m_light_reach = 0.0;
    m_dirty = true;
}

uint32_t Scene::add_light(const LightDesc& desc) {
    if (!is_finite(desc.radiance) || min_component(desc.radiance) < 0.f)
        CMLT_THROW(SceneError, "add_light: radiance must be finite and >= 0");
    auto nonneg = [](float v, const char* name) {
        if (!(v >= 0.f) || !std::isfinite(v))
            CMLT_THROW(SceneError, "add_light: " << name << " must be finite and >= 0, got " << v);
    };
    nonneg(desc.width, "width");
    nonneg(desc.height, "height");
    nonneg(desc.radius, "radius");
    nonneg(desc.length, "length");
    if (desc.texture_id >= 0 &&
        !(desc.kind == LightDesc::Kind::dome || desc.kind == LightDesc::Kind::rect))
        CMLT_THROW(SceneError, "add_light: only dome and rect lights take a texture");
    if (desc.texture_id >= int32_t(m_textures.size()))
        CMLT_THROW(SceneError, "add_light: texture id " << desc.texture_id << " not registered ("
                                                         << m_textures.size() << " textures)");
    if (desc.kind != LightDesc::Kind::distant && desc.kind != LightDesc::Kind::dome) {
        double size = std::max({double(desc.width), double(desc.height), double(desc.radius),
                                double(desc.length)});
        double reach = affine_reach(desc.transform, size);
        if (!(reach <= k_max_coordinate))
            CMLT_THROW(SceneError, "add_light: its position and size reach " << reach
                                       << ", beyond the " << k_max_coordinate
                                       << " the renderer can trace");
        m_light_reach = std::max(m_light_reach, reach);
    }
    std::unique_ptr<Light> light;
    switch (desc.kind) {
        case LightDesc::Kind::rect: light.reset(new RectLight(desc)); break;
        case LightDesc::Kind::disk: light.reset(new DiskLight(desc)); break;
        case LightDesc::Kind::sphere: light.reset(new SphereLight(desc)); break;
        case LightDesc::Kind::distant: light.reset(new DistantLight(desc)); break;
        case LightDesc::Kind::dome: light.reset(new DomeLight(desc)); break;
        case LightDesc::Kind::cylinder: light.reset(new CylinderLight(desc)); break;
    }
    m_analytic.push_back(std::move(light));
    m_dirty = true;
    return uint32_t(m_analytic.size() - 1);
}

void Scene::set_camera(const CameraDesc& desc) {
    desc.validate();
    const double reach = affine_reach(desc.transform, 0.0);
    if (!(reach <= k_max_coordinate))
        CMLT_THROW(SceneError, "set_camera: its position reaches " << reach << ", beyond the "
                                   << k_max_coordinate << " the renderer can trace");
    m_camera = desc;
    m_has_camera = true;
}

void Scene::compute_bounds() {
    Vec3 lo(k_infinity), hi(-k_infinity);
    for (const Instance& inst : m_instances) {
        const Mesh& m = m_meshes[inst.mesh_id];
        if (m.data.n_points == 0) continue;
        double reach = max_abs(m.bbox_min, m.bbox_max);
        if (!(reach <= k_max_coordinate))
            CMLT_THROW(SceneError, "mesh '" << m.name << "': points reach " << reach
                                            << ", beyond the " << k_max_coordinate
                                            << " the renderer can trace");
        const size_t n_steps = std::max<size_t>(1, inst.motion.size());
        for (size_t k = 0; k < n_steps; ++k) {
            const Mat4& xm = inst.motion.empty() ? inst.xf.m : inst.motion[k];
            Vec3 ilo(k_infinity), ihi(-k_infinity);
            for (int c = 0; c < 8; ++c) {
                Vec3 p((c & 1) ? m.bbox_max.x : m.bbox_min.x, (c & 2) ? m.bbox_max.y : m.bbox_min.y,
                       (c & 4) ? m.bbox_max.z : m.bbox_min.z);
                Vec3 w = xm.transform_point(p);
                ilo = vmin(ilo, w);
                ihi = vmax(ihi, w);
            }
            reach = max_abs(ilo, ihi);
            if (!(reach <= k_max_coordinate))
                CMLT_THROW(SceneError, "mesh '" << m.name << "': world-space coordinates reach "
                                                << reach << ", beyond the " << k_max_coordinate
                                                << " the renderer can trace");
            lo = vmin(lo, ilo);
            hi = vmax(hi, ihi);
        }
    }
    if (m_has_camera) {
        Vec3 c = m_camera.transform.transform_point(Vec3(0.f));
        lo = vmin(lo, c);
        hi = vmax(hi, c);
    }
    if (!(lo.x <= hi.x)) {
        m_center = Vec3(0.f);
        m_radius = 1.f;
        return;
    }
    m_center = (lo + hi) * 0.5f;
    m_radius = std::max(1e-6f, 0.5f * length(hi - lo));
    check_instance_conditioning(std::max({max_abs(lo, hi), m_light_reach, 1.0}) * 4.0);
}

void Scene::check_instance_conditioning(double extent) const {
    // Rays start in the world bounds (the camera's position included), on a light or on
    // the disk infinite lights emit from (within sqrt(2) bounding radii of the centre:
    // at most (1 + sqrt(6)) times the bounds' reach): all inside the cube of `extent`,
    // 4x the largest reach.
    for (const Instance& inst : m_instances) {
        if (m_meshes[inst.mesh_id].data.n_points == 0) continue;
        const size_t n_steps = std::max<size_t>(1, inst.motion.size());
        for (size_t k = 0; k < n_steps; ++k) {
            const Mat4 inv = inst.motion.empty() ? inst.xf.inv : inst.motion[k].inverse();
            double reach = affine_reach(inv, extent);
            if (!(reach <= k_max_object_coordinate))
                CMLT_THROW(SceneError, "mesh '" << m_meshes[inst.mesh_id].name
                                       << "': rays of the scene (extent " << extent << ") reach "
                                       << reach << " in its object space, beyond the "
                                       << k_max_object_coordinate << " the renderer can trace "
                                       << "(a degenerate, near-zero scale, or a scene too large)");
        }
    }
}

void Scene::build_lights() {
    m_lights.clear();
    m_infinite.clear();
    m_analytic_area.clear();
    m_area_bounds.clear();
    m_triangle_lights.clear();
    m_tri_light_index.assign(m_instances.size(), {});
    for (auto& l : m_analytic) {
        if (l->texture_id() >= 0 && size_t(l->texture_id()) < m_textures.size())
            l->bind_texture(&m_textures[size_t(l->texture_id())]);
        l->preprocess(m_center, m_radius);
        uint32_t idx = uint32_t(m_lights.size());
        if (l->is_infinite()) m_infinite.push_back(idx);
        if (l->is_analytic_area()) {
            m_analytic_area.push_back(idx);
            AreaBound b;
            Vec3 c;
            float r = 0.f;
            if (l->bounding_sphere(&c, &r) && std::isfinite(r) && is_finite(c)) {
                // 0.1 % more radius and an absolute margin of the light's scale: the
                // culling test is float, the lights' own tests are not all.
                const float rr = r * 1.001f + 1e-6f * (max_component(vabs(c)) + r);
                b.center = c;
                b.r2 = rr * rr;
            }
            b.planar = dynamic_cast<const PlanarLight*>(l.get()) != nullptr;
            m_area_bounds.push_back(b);
        }
        m_lights.push_back(l.get());
    }
    m_first_triangle_light = m_lights.size();
    // Every emissive triangle of every instance becomes an area light.
    for (uint32_t ii = 0; ii < m_instances.size(); ++ii) {
        const Instance& inst = m_instances[ii];
        const Mesh& mesh = m_meshes[inst.mesh_id];
        std::vector<int32_t>* map = nullptr;
        for (uint32_t prim = 0; prim < mesh.data.n_tris; ++prim) {
            const Material& mat = m_materials[mesh.material_id(prim)];
            if (!mat.is_emissive()) continue;
            uint32_t v[3];
            mesh.triangle(prim, v);
            Vec3 p0 = inst.xf.m.transform_point(mesh.point(v[0]));
            Vec3 p1 = inst.xf.m.transform_point(mesh.point(v[1]));
            Vec3 p2 = inst.xf.m.transform_point(mesh.point(v[2]));
            auto tl = std::make_unique<TriangleLight>(p0, p1, p2, mat.emission, ii, prim);
            if (mat.tex_emission >= 0) {
                Vec2 st[3] = {Vec2(0.f, 0.f), Vec2(1.f, 0.f), Vec2(0.f, 1.f)};
                if (mesh.data.uvs)
                    for (int k = 0; k < 3; ++k) st[k] = mesh.uv(v[k]);
                tl->set_texture(&m_textures[size_t(mat.tex_emission)], st[0], st[1], st[2]);
            }
            if (!(tl->area() > 0.f)) continue;  // degenerate: never sampled, never hit
            if (!map) {
                map = &m_tri_light_index[ii];
                map->assign(mesh.data.n_tris, -1);
            }
            (*map)[prim] = int32_t(m_lights.size());
            m_lights.push_back(tl.get());
            m_triangle_lights.push_back(std::move(tl));
        }
    }
    // Selection by power with a floor: no light gets probability 0.
    std::vector<double> w(m_lights.size());
    double total = 0;
    for (size_t i = 0; i < m_lights.size(); ++i) {
        double p = m_lights[i]->power();
        w[i] = std::isfinite(p) && p > 0 ? p : 0.0;
        total += w[i];
    }
    if (!m_lights.empty()) {
        double floor = total > 0 ? k_light_power_floor * total / double(m_lights.size()) : 1.0;
        for (double& x : w) x = std::max(x, floor);
    }
    m_light_dist = DiscreteDistribution(w);
}

void Scene::commit() {
    for (size_t mi = 0; mi < m_meshes.size(); ++mi) {
        const Mesh& mesh = m_meshes[mi];
        if (mesh.data.material_id_all >= m_materials.size())
            CMLT_THROW(SceneError, "mesh '" << mesh.name << "': material id "
                                            << mesh.data.material_id_all << " but there are "
                                            << m_materials.size() << " materials");
        if (!mesh.data.material_ids) continue;
        for (size_t t = 0; t < mesh.data.n_tris; ++t) {
            if (mesh.data.material_ids[t] >= m_materials.size())
                CMLT_THROW(SceneError, "mesh '" << mesh.name << "': material_ids[" << t << "] = "
                                                << mesh.data.material_ids[t] << " but there are "
                                                << m_materials.size() << " materials");
        }
    }
    for (size_t i = 0; i < m_materials.size(); ++i) {
        const Material& m = m_materials[i];
        const int32_t ids[] = {m.tex_diffuse,  m.tex_emission,  m.tex_specular,
                               m.tex_normal,   m.tex_metallic,  m.tex_roughness,
                               m.tex_clearcoat, m.tex_clearcoat_roughness, m.tex_opacity};
        for (int32_t id : ids)
            if (id >= 0 && size_t(id) >= m_textures.size())
                CMLT_THROW(SceneError, "material " << i << " refers to texture " << id
                                                   << " but there are " << m_textures.size()
                                                   << " textures");
        const std::pair<int8_t, int> pvs[] = {{m.pv_diffuse, 3},   {m.pv_specular, 3},
                                              {m.pv_metallic, 1},  {m.pv_roughness, 1},
                                              {m.pv_clearcoat, 1}, {m.pv_clearcoat_roughness, 1},
                                              {m.pv_opacity, 1}};
        for (const auto& pv : pvs)
            if (pv.first >= 0 && int(pv.first) + pv.second > k_max_primvar_columns)
                CMLT_THROW(SceneError, "material " << i << " reads primvar columns " << int(pv.first)
                                                   << ".." << int(pv.first) + pv.second - 1
                                                   << " but meshes carry at most "
                                                   << k_max_primvar_columns);
    }
    // Which materials can let rays pass (visibility queries step through them only then).
    m_material_passes.assign(m_materials.size(), 0);
    m_pass_through = false;
    for (size_t i = 0; i < m_materials.size(); ++i) {
        if (!may_pass_rays(m_materials[i])) continue;
        m_material_passes[i] = 1;
        m_pass_through = true;
    }
    classify_constant_lambert();
    m_accel->commit();
    place_static_instances();
    make_corner_sources();
    compute_bounds();
    build_lights();
    build_light_proxies();
    m_accel->commit();  // the light proxies' geometry, if it changed
    m_dirty = false;
}

void Scene::build_light_proxies() {
    m_light_proxies = false;
    m_shadow_skip_proxy.assign(m_lights.size(), k_invalid_id);
    std::vector<float> boxes;
    bool bounded = m_light_proxies_enabled && !m_analytic_area.empty();
    for (size_t k = 0; bounded && k < m_analytic_area.size(); ++k) {
        Vec3 lo, hi;
        if (!m_lights[m_analytic_area[k]]->bounding_box(&lo, &hi) || !is_finite(lo) || !is_finite(hi)) {
            bounded = false;
            break;
        }
        // A margin for the lights' float tests (their hit points can lie a few ulps
        // outside the exact box; a flat light's box has no thickness): 10^-4 of the
        // box's size and 10^-5 of its distance from the origin, plus a floor.
        const float pad = 1e-4f * max_component(hi - lo) + 1e-5f * std::max(max_component(vabs(lo)),
                                                                           max_component(vabs(hi))) + 1e-7f;
        for (float v : {lo.x - pad, lo.y - pad, lo.z - pad, hi.x + pad, hi.y + pad, hi.z + pad}) boxes.push_back(v);
        if (m_area_bounds[k].planar) m_shadow_skip_proxy[m_analytic_area[k]] = uint32_t(k);
    }
    if (!bounded) {
        m_shadow_skip_proxy.assign(m_lights.size(), k_invalid_id);
        m_accel->set_light_proxies(nullptr, nullptr, 0);
        return;
    }
    m_accel->set_light_proxies(&m_proxies, boxes.data(), m_analytic_area.size());
    m_light_proxies = true;
}

void Scene::place_static_instances() {
    // Large meshes keep placing their triangles per hit: a world-space copy of a big
    // mesh is one more array the hits miss the cache on (on the 1M-triangle dense
    // shot it made pt slower), while the transform it saves is small next to their
    // traversal.
    std::vector<uint32_t> uses(m_meshes.size(), 0);
    for (const Instance& inst : m_instances) ++uses[inst.mesh_id];
    for (size_t i = 0; i < m_instances.size(); ++i) {
        const Instance& inst = m_instances[i];
        const Mesh& mesh = m_meshes[inst.mesh_id];
        std::vector<float>& placed = m_placed[i];
        if (uses[inst.mesh_id] != 1 || inst.motion.size() > 1 || mesh.data.n_points > k_place_max_points) {
            std::vector<float>().swap(placed);
            continue;
        }
        if (!m_placed_stale[i] && !placed.empty()) continue;
        placed.resize(3 * mesh.data.n_points);
        for (uint32_t k = 0; k < mesh.data.n_points; ++k) {
            const Vec3 q = inst.xf.m.transform_affine_point(mesh.point(k));  // as fill_interaction does
            placed[3 * k] = q.x;
            placed[3 * k + 1] = q.y;
            placed[3 * k + 2] = q.z;
        }
        m_placed_stale[i] = 0;
    }
}

void Scene::make_corner_sources() {
    m_corner_sources.assign(m_instances.size(), CornerSource());
    for (size_t i = 0; i < m_instances.size(); ++i) {
        const Instance& inst = m_instances[i];
        const MeshData& d = m_meshes[inst.mesh_id].data;
        CornerSource& c = m_corner_sources[i];
        c.indices = d.indices;
        c.placed = m_placed[i].empty() ? nullptr : m_placed[i].data();
        c.points = d.points;
        c.normals = d.normals;
        c.uvs = d.uvs;
        c.material_ids = d.material_ids;
        c.xf = &inst.xf.m;
        c.normal = &inst.xf.normal;
        c.material_id_all = d.material_id_all;
        c.moving = inst.motion.size() > 1;
        c.primvars = d.n_primvar_columns > 0;
    }
}

void Scene::require_committed(const char* what) const {
    if (m_dirty) CMLT_THROW(SceneError, what << ": the scene changed since the last commit(); call commit()");
}

int32_t Scene::triangle_light_index(uint32_t instance_id, uint32_t prim_id) const {
    if (instance_id >= m_tri_light_index.size()) return -1;
    const auto& map = m_tri_light_index[instance_id];
    return prim_id < map.size() ? map[prim_id] : -1;
}

const TriangleLight& Scene::triangle_light(size_t light_index) const {
    CMLT_DCHECK(light_index >= m_first_triangle_light);
    return *m_triangle_lights[light_index - m_first_triangle_light];
}

}  // namespace cmlt
