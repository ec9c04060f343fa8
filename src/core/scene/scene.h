#pragma once
/// \file The flattened render scene of one frame.
///
/// Owns meshes (zero-copy views of caller arrays kept alive by `MeshData::owner`),
/// instances (a mesh placed by a transform), the material table, analytic lights and the
/// camera. Edits mark the scene dirty; `commit()` refits/rebuilds what changed, rebuilds
/// the light list (analytic lights + one TriangleLight per emissive triangle of every
/// instance) and the light-selection distribution (proportional to power, with a floor).
///
/// Queries are const and thread-safe after `commit()`.
#include "accel/accel.h"
#include "cameras/camera.h"
#include "lights/light.h"
#include "lights/triangle_light.h"
#include "materials/material.h"
#include "sampling/discrete_distribution.h"
#include "scene/interaction.h"
#include "scene/mesh.h"
#include "textures/texture.h"

#include <memory>
#include <string>
#include <vector>

namespace cmlt {

struct Instance {
    uint32_t mesh_id = 0;
    Transform xf;  ///< object -> world, inverse, normal matrix (time 0 when moving)
    /// Motion blur: object -> world at >= 2 time steps evenly spaced over the shutter
    /// (ray time 0 .. 1), interpolated linearly per matrix entry as Embree does; empty
    /// for an instance without motion blur.
    std::vector<Mat4> motion;
    /// Object -> world at shutter time `time` (xf.m when not moving).
    Mat4 matrix_at(float time) const;
};

/// What a ray hit first: a mesh surface, an analytic light's emitting side, or nothing.
struct SceneHit {
    enum class Kind { miss, surface, light };
    Kind kind = Kind::miss;
    SurfaceInteraction si;       ///< kind == surface
    uint32_t light_index = 0;    ///< kind == light: index into lights()
    Spectrum le{0.f};            ///< kind == light: emitted radiance
    float t = k_infinity;
};

/// The surface geometry of a mesh hit, what Scene::fill_interaction computes first
/// (point, normals, direction to the ray origin, offset scale) and the hit triangle's
/// material: all the diffuse fast path of the path tracer reads (Scene::hit_geometry).
struct HitGeometry {
    SurfacePoint sp;
    Vec3 ns;  ///< unit shading normal, on the side of sp.ng
    Vec3 wo;  ///< unit direction toward the ray origin
    uint32_t material_id = 0;
};

/// The corners of a static instance's hit triangle, what the path tracer's diffuse lanes
/// gather (integrators/path/diffuse_lanes.h; Scene::triangle_corners): world-space
/// points as hit_geometry places them, and with vertex normals the object-space corner
/// normals and the instance's normal matrix (null without).
struct TriangleCorners {
    Vec3 p[3];
    const float* n[3] = {nullptr, nullptr, nullptr};
    const Mat4* normal = nullptr;
    const float* uv[3] = {nullptr, nullptr, nullptr};  ///< the corners' uvs (null: none)
    bool primvars = false;                              ///< the mesh has primvar columns
    uint32_t material_id = 0;
};

/// Fraction of the mean light power given to every light at least (so none has pmf 0).
constexpr double k_light_power_floor = 1e-3;

/// Scene::transmittance steps through at most this many pass-through surfaces; a shadow
/// ray crossing more counts as blocked (a bias only for > 256 stacked cut-outs).
constexpr int k_max_pass_through_crossings = 256;

class Scene {
public:
    Scene();
    ~Scene();
    Scene(const Scene&) = delete;
    Scene& operator=(const Scene&) = delete;

    // ---- edits -----------------------------------------------------------------
    /// Validates and registers a mesh; throws SceneError naming `name`.
    uint32_t add_mesh(const std::string& name, MeshData data);
    /// New points (same count) and optionally new normals; `owner` keeps them alive.
    void update_mesh_points(uint32_t mesh_id, const float* points, size_t n_points,
                            const float* normals, std::shared_ptr<void> owner);
    uint32_t add_instance(uint32_t mesh_id, const Mat4& object_to_world);
    void set_instance_transform(uint32_t instance_id, const Mat4& object_to_world);
    /// Motion blur: `steps.size()` >= 2 transforms evenly spaced over the shutter (ray
    /// time 0..1). One step is set_instance_transform. Lights built from emissive
    /// triangles of a moving instance use its first step.
    void set_instance_motion(uint32_t instance_id, const std::vector<Mat4>& steps);
    /// Some instance carries motion-blur time steps: the renderer then samples a
    /// ray time per camera sample (and only then).
    bool motion_blur() const;
    /// K >= 1 rows; material_ids index these.
    void set_materials(std::vector<Material> materials);
    /// The material kernels of the next renders (analysis/kernel_select.h): `general`
    /// renders every preview material through the full UsdPreviewSurface model; otherwise
    /// the exact Lambertians go through the diffuse-only kernel. Returns how many do.
    int select_kernels(bool general);
    /// Registers an image texture (zero copy; `desc.owner` keeps it alive); returns its id,
    /// which material texture slots and textured lights refer to.
    uint32_t add_texture(TextureDesc desc, const std::string& name = "texture");
    void clear_lights();
    /// Validates and adds an analytic light; returns its id (index among analytic lights).
    uint32_t add_light(const LightDesc& desc);
    void set_camera(const CameraDesc& desc);
    void commit();

    // ---- state -----------------------------------------------------------------
    bool dirty() const { return m_dirty; }
    bool has_camera() const { return m_has_camera; }
    const CameraDesc& camera_desc() const { return m_camera; }
    size_t mesh_count() const { return m_meshes.size(); }
    size_t instance_count() const { return m_instances.size(); }
    const Mesh& mesh(uint32_t id) const { return m_meshes[id]; }
    const Instance& instance(uint32_t id) const { return m_instances[id]; }
    const Material& material(uint32_t id) const { return m_materials[id]; }
    size_t material_count() const { return m_materials.size(); }
    const std::vector<Texture>& textures() const { return m_textures; }
    size_t texture_count() const { return m_textures.size(); }
    const Accel& accel() const { return *m_accel; }
    Vec3 bounds_center() const { return m_center; }
    float bounds_radius() const { return m_radius; }

    // ---- lights (after commit) -----------------------------------------------------
    size_t light_count() const { return m_lights.size(); }
    const Light& light(size_t i) const { return *m_lights[i]; }
    float light_pmf(size_t i) const { return m_light_dist.pmf(i); }
    /// Pick a light by power; returns its index, pmf in *pmf. Requires light_count() > 0.
    size_t sample_light(float u, float* pmf) const { return m_light_dist.sample(u, pmf); }
    const std::vector<uint32_t>& infinite_lights() const { return m_infinite; }
    /// Light index of an emissive triangle, or -1.
    int32_t triangle_light_index(uint32_t instance_id, uint32_t prim_id) const;
    const TriangleLight& triangle_light(size_t light_index) const;
    /// Entries of the per-instance emissive-triangle maps (one per triangle of an
    /// instance with an emitter), for scene_memory().
    /// Bytes of the world-space point caches of static instances (m_placed).
    size_t placed_point_bytes() const {
        size_t n = 0;
        for (const auto& p : m_placed) n += p.capacity() * sizeof(float);
        return n;
    }
    size_t light_map_entries() const {
        size_t n = 0;
        for (const auto& map : m_tri_light_index) n += map.size();
        return n;
    }

    // ---- queries (after commit) ----------------------------------------------------
    SceneHit intersect(const Ray& ray) const;
    /// Scene::intersect for a mesh hit `h` of `ray` found elsewhere (e.g. a packet
    /// query): tests the analytic emitters up to h (unless the query tested the light
    /// proxies: Hit::light) and fills the interaction.
    SceneHit resolve_hit(const Ray& ray, const Hit& h) const;
    bool intersect_surface(const Ray& ray, SurfaceInteraction* si) const;
    bool occluded(const Ray& ray) const { return m_accel->occluded(ray); }
    /// Some material can let a ray through without scattering (materials/material_eval.h
    /// may_pass_rays: cut-outs, ior-1 interfaces with opacity < 1), after commit().
    bool has_pass_through() const { return m_pass_through; }
    /// Can a hit on material `material_id` be a pass-through crossing?
    bool material_passes(uint32_t material_id) const {
        return m_pass_through && m_material_passes[material_id] != 0;
    }
    /// Visibility of a shadow ray (ray.tnear .. ray.tfar), what integrators use instead of
    /// occluded() (cut-outs and pass-through surfaces let camera and BSDF rays
    /// through, so they must let shadow rays through too). Returns 0 if an opaque surface
    /// or an analytic light (blocked_by_light) blocks the ray, otherwise the product T of the pass-through weights of the
    /// surfaces it crosses, each evaluated at the hit as a camera path's BSDF is there
    /// (make_bsdf: textured opacity and cut-out at the hit's uv, normal map;
    /// Bsdf::pass_through). *pass_pdf gets the product of the probabilities with which
    /// BSDF sampling takes those crossings: a random walk makes the same segment with
    /// that extra density factor, which MIS weights need. Without pass-through
    /// materials it is !occluded(ray) with *pass_pdf = 1 and costs nothing more; with
    /// them an unblocked ray still costs one occlusion query.
    float transmittance(const Ray& ray, float* pass_pdf) const;
    /// transmittance() for a ray that blocked_by_light() let pass, given whether the BVH
    /// reports it occluded (Accel::occluded, or a lane of an occlusion packet): 1 if not,
    /// else the stepping through pass-through surfaces (0 without them). The same value
    /// and *pass_pdf as transmittance(); for visibility queries answered in packets.
    float transmittance_given(const Ray& ray, bool occluded, float* pass_pdf) const {
        *pass_pdf = 1.f;
        if (!occluded) return 1.f;
        return transmittance_through(ray, pass_pdf);
    }
    /// Does an analytic area light (rect, disk, sphere, cylinder: not in the BVH) lie on
    /// `ray` within (tnear, tfar), seen from a side it stops rays on (Light::intersect)?
    bool blocked_by_light(const Ray& ray) const;
    /// blocked_by_light for next-event estimation's shadow ray toward a point sampled on
    /// light `target` (a Scene::light index; k_no_light: none) and aimed by
    /// shadow_target: a planar light (rect, disk) is not tested against its own ray. The
    /// ray ends short of its plane on the ray's side (1 - k_shadow_epsilon of the way),
    /// so the light cannot block it; its float intersect reported a block where rounding
    /// eats that margin (grazing rays, points close to a light far from the origin: test
    /// LightSampling.NextEventShadowRaysAreNotBlockedByTheirOwnPlanarLight).
    bool blocked_by_light(const Ray& ray, size_t target) const;
    static constexpr size_t k_no_light = ~size_t(0);
    /// transmittance() of such a shadow ray.
    float transmittance(const Ray& ray, size_t target, float* pass_pdf) const;
    void fill_interaction(const Ray& ray, const Hit& hit, SurfaceInteraction* si) const;
    /// The part of fill_interaction a diffuse shading point needs (the same floats).
    void hit_geometry(const Ray& ray, const Hit& hit, HitGeometry* g) const;
    /// The corners of `hit`'s triangle (TriangleCorners); false for a moving instance
    /// (placed at the ray's time: hit_geometry).
    bool triangle_corners(const Hit& hit, TriangleCorners* c) const;
    /// The nearest analytic area light `ray` sees within (tnear, tmax): its t (k_infinity
    /// if none), index and emitted radiance (resolve_hit's test).
    float nearest_light(const Ray& ray, float tmax, uint32_t* light_index, Spectrum* le) const;
    /// Some analytic area light (not in the BVH: nearest_light tests them) exists.
    bool has_analytic_area_lights() const { return !m_analytic_area.empty(); }
    /// The analytic area lights are light proxies of the BVH (after commit): queries with
    /// `lights` (Accel::intersect, intersect_lanes) find them, their hits carry
    /// Hit::light, and resolve_hit takes such hits without testing the lights again.
    bool light_proxies() const { return m_light_proxies; }
    /// Off: the lights stay out of the BVH (the scalar test after every query); takes
    /// effect at the next commit(). For tests comparing the two.
    void set_light_proxies_enabled(bool on) {
        m_light_proxies_enabled = on;
        m_dirty = true;
    }
    /// The light proxy a shadow ray toward light `target` skips (Accel::occluded's
    /// skip_light; blocked_by_light(ray, target)): a planar light's own, else none.
    uint32_t shadow_skip_proxy(size_t target) const {
        return target < m_shadow_skip_proxy.size() ? m_shadow_skip_proxy[target] : k_invalid_id;
    }
    /// transmittance(ray, target, pass_pdf) for a ray whose BVH occlusion query tested
    /// the light proxies (skipping shadow_skip_proxy(target)): `occluded` is its answer.
    float transmittance_given_lights(const Ray& ray, size_t target, bool occluded, float* pass_pdf) const {
        *pass_pdf = 1.f;
        if (!occluded) return 1.f;
        if (!m_pass_through || blocked_by_light(ray, target)) return 0.f;
        return transmittance_through(ray, pass_pdf);
    }
    /// The constant Lambertian reflectance a hit on `material_id` shades with, if the
    /// material is one the path tracer's diffuse fast path takes: a Lambertian (legacy
    /// Lambert, or a preview material the diffuse-only kernel renders) without textures,
    /// primvars, normal map or emission, opaque. Null otherwise. After commit() and
    /// select_kernels().
    const Spectrum* constant_lambert(uint32_t material_id) const {
        return m_constant_lambert[material_id] ? &m_lambert_r[material_id] : nullptr;
    }
    /// The BSDF a hit on `material_id` shades with when it is the same at every hit and
    /// its geometry alone places it (PathBatch's lanes): a UsdPreviewSurface with constant
    /// inputs (Material::constant_bsdf), no normal map, no emission, opaque, not a
    /// constant Lambertian. Null otherwise. After commit() and select_kernels().
    const PreviewSurfaceBsdf* constant_preview(uint32_t material_id) const {
        return m_constant_preview[material_id];
    }
    /// The material, if PathBatch's lanes may place its hits and make its BSDF from the
    /// hit's uv and normals alone (make_bsdf_at): no normal map, no emission, opaque,
    /// neither constant_lambert nor constant_preview. Null otherwise. (Its mesh must have
    /// no primvar columns: TriangleCorners::primvars.)
    const Material* lane_material(uint32_t material_id) const {
        return m_lane_material[material_id] ? &m_materials[material_id] : nullptr;
    }

private:
    /// transmittance() past a BVH occlusion: step through the hits in order.
    float transmittance_through(const Ray& ray, float* pass_pdf) const;
    void require_committed(const char* what) const;
    void build_lights();
    /// The world bounds (m_center, m_radius); refuses coordinates beyond what the
    /// renderer can trace (scene/coordinate_range.h), naming the mesh (set_camera and
    /// add_light check the camera and the lights).
    void compute_bounds();
    /// Refuses an instance whose inverse maps the world cube `extent` out of range.
    void check_instance_conditioning(double extent) const;

    std::unique_ptr<Accel> m_accel;
    std::vector<Mesh> m_meshes;
    std::vector<std::shared_ptr<void>> m_point_owners;  ///< per mesh, latest update_mesh_points
    std::vector<Instance> m_instances;
    /// Per instance: its mesh's points placed in world space (3 floats each), cached at
    /// commit for a static instance of a small mesh placed once (place_static_instances), so a
    /// hit needs no transform; empty otherwise. The same floats fill_interaction
    /// computed per hit before (Mat4::transform_affine_point).
    std::vector<std::vector<float>> m_placed;
    /// Meshes with more points than this are not placed (place_static_instances).
    static constexpr uint32_t k_place_max_points = 1u << 16;
    std::vector<uint8_t> m_placed_stale;  ///< per instance: transform or points changed
    void place_static_instances();
    /// Per instance, made at commit: what triangle_corners reads, in one record instead
    /// of the instance, its mesh and its placed points (a hit's corners are gathered for
    /// every diffuse lane).
    struct CornerSource {
        const uint32_t* indices = nullptr;
        const float* placed = nullptr;   ///< m_placed's world-space points, or null
        const float* points = nullptr;   ///< the mesh's object-space points
        const float* normals = nullptr;  ///< the mesh's, or null
        const float* uvs = nullptr;      ///< the mesh's, or null
        const uint32_t* material_ids = nullptr;
        const Mat4* xf = nullptr;        ///< object to world
        const Mat4* normal = nullptr;    ///< the normal matrix
        uint32_t material_id_all = 0;
        bool moving = false;
        bool primvars = false;
    };
    std::vector<CornerSource> m_corner_sources;
    void make_corner_sources();
    std::vector<Material> m_materials;
    std::vector<uint8_t> m_material_passes;  ///< per material: may_pass_rays (at commit)
    std::vector<uint8_t> m_constant_lambert;  ///< per material: constant_lambert applies
    std::vector<const PreviewSurfaceBsdf*> m_constant_preview;  ///< per material: constant_preview
    std::vector<uint8_t> m_lane_material;                        ///< per material: lane_material
    std::vector<Spectrum> m_lambert_r;        ///< its reflectance
    void classify_constant_lambert();
    bool m_pass_through = false;             ///< some entry of m_material_passes is set
    std::vector<Texture> m_textures;
    std::vector<std::unique_ptr<Light>> m_analytic;  ///< as added
    double m_light_reach = 0.0;  ///< largest affine_reach of a finite analytic light
    std::vector<std::unique_ptr<TriangleLight>> m_triangle_lights;
    std::vector<const Light*> m_lights;               ///< analytic, then triangles
    std::vector<uint32_t> m_infinite;
    std::vector<uint32_t> m_analytic_area;
    /// Per entry of m_analytic_area: a sphere around what the light's intersect can hit
    /// (Light::bounding_sphere), radius squared; r2 = inf: no bound.
    struct AreaBound {
        Vec3 center;
        float r2 = k_infinity;
        bool planar = false;  ///< a PlanarLight (blocked_by_light(ray, target))
    };
    std::vector<AreaBound> m_area_bounds;
    /// The analytic area lights as the BVH's light proxies (Accel::set_light_proxies),
    /// so a camera or BSDF ray's one traversal finds the nearest of meshes and lights:
    /// proxy k is m_analytic_area[k], tested by its Light::intersect. Used when every
    /// analytic light has a bounding box (m_light_proxies); otherwise nearest_light
    /// tests them after the BVH query, as without proxies.
    class AnalyticLightProxies final : public LightProxies {
    public:
        explicit AnalyticLightProxies(const Scene& s) : m_scene(s) {}
        bool intersect(uint32_t k, const Ray& ray, float* t) const override;

    private:
        const Scene& m_scene;
    };
    AnalyticLightProxies m_proxies{*this};
    bool m_light_proxies = false;
    bool m_light_proxies_enabled = true;
    /// Per light: the proxy a shadow ray toward it skips (a planar light's own:
    /// blocked_by_light(ray, target)), k_invalid_id if none.
    std::vector<uint32_t> m_shadow_skip_proxy;
    void build_light_proxies();
    /// Can `ray` (within (tnear, tmax)) reach analytic light k (m_analytic_area[k])?
    /// Conservative: false only when the segment stays clear of the light's sphere.
    bool may_reach_light(const Ray& ray, float tmax, size_t k) const;
    std::vector<std::vector<int32_t>> m_tri_light_index;  ///< per instance: prim -> light
    size_t m_first_triangle_light = 0;
    DiscreteDistribution m_light_dist;
    CameraDesc m_camera;
    bool m_has_camera = false;
    bool m_dirty = true;
    Vec3 m_center;
    float m_radius = 1.f;
};

}  // namespace cmlt
