#include "accel/accel.h"

#include "util/cycle_clock.h"

#include "accel/embree_device.h"
#include "util/error.h"

#include <algorithm>
#include <vector>

namespace cmlt {

// Scene flags, documented choices:
// * mesh scenes: RTC_SCENE_FLAG_ROBUST (no watertightness shortcuts; grazing rays at
//   shared edges do not leak) and RTC_BUILD_QUALITY_MEDIUM. A mesh of at least
//   k_compact_bvh_triangles also gets RTC_SCENE_FLAG_COMPACT: leaves that index the shared
//   vertex buffer instead of copying the vertices (a 1M-triangle sphere: 37 instead of 65
//   bytes of BVH per triangle), at the price of slower queries (rtcIntersect1 on the
//   Cornell box: ~15 % more instructions), so small meshes keep the default leaves. The
//   hits are the same either way (the 64 fingerprint renders are bit-identical). A deforming mesh rebuilds
//   only its own BVH; its geometry uses RTC_BUILD_QUALITY_REFIT after the first update,
//   so a per-frame point update refits instead of rebuilding.
// * top-level scene: RTC_SCENE_FLAG_DYNAMIC + RTC_BUILD_QUALITY_MEDIUM (instance
//   transforms change every frame). Not LOW (Embree's Morton builder, hdEmbree's
//   choice): its BVH differed from build to build, so where instances coincide (a ray
//   hits several at the same t) the instance reported changed from one process to the
//   next and so did the image (tests/cpp/accel: CoincidentInstances...). The binned SAH
//   build is the same every time, and on 20,000 instances it rebuilt in 5.6 ms against
//   LOW's 12 ms here (2 cores), queries equal.

namespace {
// Embree geometry ids of the top level: the light proxies' user geometry, then the
// instances (instance i is id i + 1; Hit::instance_id is i).
constexpr unsigned k_light_geom_id = 0;
constexpr unsigned k_first_instance_geom_id = 1;
}  // namespace

/// The light proxies' user geometry's data: their test and world boxes (6 floats each).
struct AccelLightData {
    const LightProxies* proxies = nullptr;
    std::vector<float> boxes;
};

struct Accel::Impl {
    struct Mesh {
        RTCScene scene = nullptr;
        RTCGeometry geom = nullptr;
        size_t n_points = 0;
        bool dirty = true;
        bool refitted = false;  ///< points updated since the last commit
        int64_t bytes = 0;      ///< Embree's memory for this mesh's scene and BVH
    };
    struct Instance {
        RTCGeometry geom = nullptr;
        uint32_t mesh = 0;
    };
    std::shared_ptr<EmbreeDevice> device = EmbreeDevice::get();
    RTCScene top = nullptr;
    std::vector<Mesh> meshes;
    std::vector<Instance> instances;
    bool top_dirty = true;
    int64_t top_bytes = 0;  ///< Embree's memory for the top level (instances and BVH)
    // The light proxies: one user geometry of the top level, Embree id k_light_geom_id
    // (instance i is Embree id i + 1), attached while there are any.
    RTCGeometry lights = nullptr;
    AccelLightData light_data;  ///< the user geometry's user data

    Impl() {
        const int64_t before = device->allocated_bytes();
        top = rtcNewScene(device->handle());
        device->check("Accel: rtcNewScene");
        rtcSetSceneFlags(top, RTC_SCENE_FLAG_DYNAMIC);
        rtcSetSceneBuildQuality(top, RTC_BUILD_QUALITY_MEDIUM);
        device->check("Accel: top-level scene flags");
        top_bytes = device->allocated_bytes() - before;
    }
    ~Impl() {
        if (lights) rtcReleaseGeometry(lights);
        for (auto& i : instances) rtcReleaseGeometry(i.geom);
        for (auto& m : meshes) {
            rtcReleaseGeometry(m.geom);
            rtcReleaseScene(m.scene);
        }
        if (top) rtcReleaseScene(top);
    }
};

Accel::Accel() : m_impl(new Impl()) {}

namespace {

/// What every query passes to Embree: its context (first, so Embree's pointer to it is
/// one to this) and whether the light proxies take part. The proxies' callbacks read
/// `lights`, so every query of the top level uses this context.
struct QueryContext {
    RTCIntersectContext ctx;
    bool lights = false;
    explicit QueryContext(bool lights_, bool coherent = false) : lights(lights_) {
        rtcInitIntersectContext(&ctx);
        if (coherent) ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    }
};

inline const QueryContext& query_context(const RTCIntersectContext* c) {
    return *reinterpret_cast<const QueryContext*>(c);
}

inline Ray ray_lane(RTCRayN* r, unsigned N, unsigned i) {
    Ray ray(Vec3(RTCRayN_org_x(r, N, i), RTCRayN_org_y(r, N, i), RTCRayN_org_z(r, N, i)),
            Vec3(RTCRayN_dir_x(r, N, i), RTCRayN_dir_y(r, N, i), RTCRayN_dir_z(r, N, i)),
            RTCRayN_tnear(r, N, i), RTCRayN_tfar(r, N, i));
    ray.time = RTCRayN_time(r, N, i);
    return ray;
}

/// Bit i set: lane i of the N rays of `r` is valid and its segment (tnear .. tfar)
/// crosses box b (6 floats) — slabs, in one loop over the lanes' SoA floats (Embree's
/// RTCRayN layout: org x, y, z, tnear, dir x, y, z, time, tfar, each N wide). A NaN (an
/// origin on a slab of a direction parallel to it) drops out of the min / max: the lane
/// is kept (conservative).
inline uint32_t lanes_crossing_box(const float* b, const RTCRayN* r, unsigned N, const int* valid) {
    const float* f = reinterpret_cast<const float*>(r);
    const float *ox = f, *oy = f + N, *oz = f + 2 * N, *tn = f + 3 * N;
    const float *dx = f + 4 * N, *dy = f + 5 * N, *dz = f + 6 * N, *tf = f + 8 * N;
    uint32_t bits = 0;
    for (unsigned i = 0; i < N; ++i) {
        const float ix = 1.f / dx[i], iy = 1.f / dy[i], iz = 1.f / dz[i];
        const float ax = (b[0] - ox[i]) * ix, bx = (b[3] - ox[i]) * ix;
        const float ay = (b[1] - oy[i]) * iy, by = (b[4] - oy[i]) * iy;
        const float az = (b[2] - oz[i]) * iz, bz = (b[5] - oz[i]) * iz;
        const float t0 = std::max(std::max(tn[i], std::min(ax, bx)), std::max(std::min(ay, by), std::min(az, bz)));
        const float t1 = std::min(std::min(tf[i], std::max(ax, bx)), std::min(std::max(ay, by), std::max(az, bz)));
        bits |= uint32_t(valid[i] == -1 && !(t0 > t1)) << i;
    }
    return bits;
}

void light_bounds(const RTCBoundsFunctionArguments* args) {
    const float* b = static_cast<const AccelLightData*>(args->geometryUserPtr)->boxes.data() + 6 * size_t(args->primID);
    RTCBounds* o = args->bounds_o;
    o->lower_x = b[0]; o->lower_y = b[1]; o->lower_z = b[2];
    o->upper_x = b[3]; o->upper_y = b[4]; o->upper_z = b[5];
}

}  // namespace

// The proxies' tests, called by Embree for rays entering a proxy's box (closest hit: the
// hit is kept if nearer than tfar, which Embree shortens as it finds nearer hits, so
// the query ends with the nearest of triangles and proxies, ties to the triangle).
struct AccelLightCallbacks {
    static void intersect(const RTCIntersectFunctionNArguments* args) {
        if (!query_context(args->context).lights) return;
        const AccelLightData& D = *static_cast<const AccelLightData*>(args->geometryUserPtr);
        const float* box = D.boxes.data() + 6 * size_t(args->primID);
        RTCRayN* ray = RTCRayHitN_RayN(args->rayhit, args->N);
        RTCHitN* hit = RTCRayHitN_HitN(args->rayhit, args->N);
        // Embree's leaves hold several primitives of the top level, so rays far from the
        // proxy's box come here too: the box first, for all lanes at once.
        for (uint32_t bits = lanes_crossing_box(box, ray, args->N, args->valid); bits; bits &= bits - 1) {
            const unsigned i = unsigned(__builtin_ctz(bits));
            float t;
            if (!D.proxies->intersect(args->primID, ray_lane(ray, args->N, i), &t)) continue;
            RTCRayN_tfar(ray, args->N, i) = t;
            RTCHitN_Ng_x(hit, args->N, i) = 0.f;
            RTCHitN_Ng_y(hit, args->N, i) = 0.f;
            RTCHitN_Ng_z(hit, args->N, i) = 1.f;
            RTCHitN_u(hit, args->N, i) = 0.f;
            RTCHitN_v(hit, args->N, i) = 0.f;
            RTCHitN_primID(hit, args->N, i) = args->primID;
            RTCHitN_geomID(hit, args->N, i) = args->geomID;
            RTCHitN_instID(hit, args->N, i, 0) = args->context->instID[0];
        }
    }
    static void occluded(const RTCOccludedFunctionNArguments* args) {
        if (!query_context(args->context).lights) return;
        const AccelLightData& D = *static_cast<const AccelLightData*>(args->geometryUserPtr);
        const float* box = D.boxes.data() + 6 * size_t(args->primID);
        for (uint32_t bits = lanes_crossing_box(box, args->ray, args->N, args->valid); bits; bits &= bits - 1) {
            const unsigned i = unsigned(__builtin_ctz(bits));
            if (RTCRayN_id(args->ray, args->N, i) == args->primID) continue;  // the skipped proxy
            float t;
            if (!D.proxies->intersect(args->primID, ray_lane(args->ray, args->N, i), &t)) continue;
            RTCRayN_tfar(args->ray, args->N, i) = -k_infinity;
        }
    }
};

void Accel::set_light_proxies(const LightProxies* proxies, const float* boxes, size_t n) {
    Impl& I = *m_impl;
    if (n == 0) {
        if (I.lights) {
            rtcDetachGeometry(I.top, k_light_geom_id);
            rtcReleaseGeometry(I.lights);
            I.lights = nullptr;
            I.top_dirty = true;
        }
        I.light_data = {};
        I.device->check("Accel::set_light_proxies");
        return;
    }
    const std::vector<float> b(boxes, boxes + 6 * n);
    if (I.lights && proxies == I.light_data.proxies && b == I.light_data.boxes) return;
    I.light_data.proxies = proxies;
    I.light_data.boxes = b;
    if (!I.lights) {
        I.lights = rtcNewGeometry(I.device->handle(), RTC_GEOMETRY_TYPE_USER);
        rtcSetGeometryUserData(I.lights, &I.light_data);
        rtcSetGeometryBoundsFunction(I.lights, light_bounds, &I.light_data);
        rtcSetGeometryIntersectFunction(I.lights, AccelLightCallbacks::intersect);
        rtcSetGeometryOccludedFunction(I.lights, AccelLightCallbacks::occluded);
        rtcAttachGeometryByID(I.top, I.lights, k_light_geom_id);
    }
    rtcSetGeometryUserPrimitiveCount(I.lights, unsigned(n));
    rtcCommitGeometry(I.lights);
    I.device->check("Accel::set_light_proxies");
    I.top_dirty = true;
}

Accel::~Accel() = default;

size_t Accel::mesh_count() const { return m_impl->meshes.size(); }
size_t Accel::instance_count() const { return m_impl->instances.size(); }

size_t Accel::mesh_bvh_bytes(uint32_t mesh_id) const {
    CMLT_CHECK(mesh_id < m_impl->meshes.size());
    return size_t(std::max<int64_t>(0, m_impl->meshes[mesh_id].bytes));
}

size_t Accel::top_level_bytes() const { return size_t(std::max<int64_t>(0, m_impl->top_bytes)); }

uint32_t Accel::add_mesh(const float* points, size_t n_points, const uint32_t* indices,
                         size_t n_tris) {
    Impl& I = *m_impl;
    RTCDevice dev = I.device->handle();
    Impl::Mesh mesh;
    const int64_t before = I.device->allocated_bytes();
    mesh.n_points = n_points;
    mesh.scene = rtcNewScene(dev);
    rtcSetSceneFlags(mesh.scene, n_tris >= k_compact_bvh_triangles
                                     ? RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_COMPACT
                                     : RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(mesh.scene, RTC_BUILD_QUALITY_MEDIUM);
    mesh.geom = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetSharedGeometryBuffer(mesh.geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, points, 0,
                               3 * sizeof(float), n_points);
    rtcSetSharedGeometryBuffer(mesh.geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, indices, 0,
                               3 * sizeof(uint32_t), n_tris);
    rtcCommitGeometry(mesh.geom);
    rtcAttachGeometryByID(mesh.scene, mesh.geom, 0);
    I.device->check("Accel::add_mesh");
    mesh.bytes = I.device->allocated_bytes() - before;
    I.meshes.push_back(mesh);
    return uint32_t(I.meshes.size() - 1);
}

void Accel::update_mesh_points(uint32_t mesh_id, const float* points) {
    Impl& I = *m_impl;
    CMLT_CHECK(mesh_id < I.meshes.size());
    Impl::Mesh& mesh = I.meshes[mesh_id];
    rtcSetGeometryBuildQuality(mesh.geom, RTC_BUILD_QUALITY_REFIT);
    rtcSetSharedGeometryBuffer(mesh.geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, points, 0,
                               3 * sizeof(float), mesh.n_points);
    rtcUpdateGeometryBuffer(mesh.geom, RTC_BUFFER_TYPE_VERTEX, 0);
    rtcCommitGeometry(mesh.geom);
    I.device->check("Accel::update_mesh_points");
    mesh.dirty = true;
    mesh.refitted = true;
    I.top_dirty = true;
}

static void to_float3x4(const Mat4& m, float out[12]) {
    // RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR: 4 columns of 3 rows.
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 3; ++r) out[c * 3 + r] = float(m.m[r][c]);
}

uint32_t Accel::add_instance(uint32_t mesh_id, const Mat4& object_to_world) {
    Impl& I = *m_impl;
    CMLT_CHECK(mesh_id < I.meshes.size());
    Impl::Instance inst;
    inst.mesh = mesh_id;
    const int64_t before = I.device->allocated_bytes();
    inst.geom = rtcNewGeometry(I.device->handle(), RTC_GEOMETRY_TYPE_INSTANCE);
    rtcSetGeometryInstancedScene(inst.geom, I.meshes[mesh_id].scene);
    rtcSetGeometryTimeStepCount(inst.geom, 1);
    float xf[12];
    to_float3x4(object_to_world, xf);
    rtcSetGeometryTransform(inst.geom, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, xf);
    rtcCommitGeometry(inst.geom);
    uint32_t id = uint32_t(I.instances.size());
    rtcAttachGeometryByID(I.top, inst.geom, id + k_first_instance_geom_id);
    I.device->check("Accel::add_instance");
    I.top_bytes += I.device->allocated_bytes() - before;
    I.instances.push_back(inst);
    I.top_dirty = true;
    return id;
}

void Accel::set_instance_transform(uint32_t instance_id, const Mat4& object_to_world) {
    Impl& I = *m_impl;
    CMLT_CHECK(instance_id < I.instances.size());
    float xf[12];
    to_float3x4(object_to_world, xf);
    RTCGeometry g = I.instances[instance_id].geom;
    rtcSetGeometryTimeStepCount(g, 1);
    rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, xf);
    rtcCommitGeometry(g);
    I.device->check("Accel::set_instance_transform");
    I.top_dirty = true;
}

void Accel::set_instance_motion(uint32_t instance_id, const Mat4* steps, uint32_t n_steps) {
    Impl& I = *m_impl;
    CMLT_CHECK(instance_id < I.instances.size());
    CMLT_CHECK(n_steps >= 1 && n_steps <= 129);  // Embree's limit on time steps
    RTCGeometry g = I.instances[instance_id].geom;
    rtcSetGeometryTimeStepCount(g, n_steps);
    for (uint32_t k = 0; k < n_steps; ++k) {
        float xf[12];
        to_float3x4(steps[k], xf);
        rtcSetGeometryTransform(g, k, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, xf);
    }
    rtcCommitGeometry(g);
    I.device->check("Accel::set_instance_motion");
    I.top_dirty = true;
}

void Accel::commit() {
    Impl& I = *m_impl;
    bool any_mesh = false;
    for (auto& m : I.meshes) {
        if (!m.dirty) continue;
        const int64_t before = I.device->allocated_bytes();
        rtcCommitScene(m.scene);
        m.bytes += I.device->allocated_bytes() - before;
        I.device->check("Accel::commit (mesh BVH)");
        m.dirty = false;
        I.top_dirty = true;
        any_mesh = true;
    }
    if (any_mesh) {
        // An instance's bounds come from its instanced scene: the top level only
        // recomputes them for instance geometries committed since its last build, so a
        // refitted (deformed) mesh must re-commit every instance placing it.
        for (auto& inst : I.instances) {
            if (!I.meshes[inst.mesh].refitted) continue;
            rtcCommitGeometry(inst.geom);
        }
        for (auto& m : I.meshes) m.refitted = false;
        I.device->check("Accel::commit (instances of deformed meshes)");
    }
    if (I.top_dirty) {
        const int64_t before = I.device->allocated_bytes();
        rtcCommitScene(I.top);
        I.top_bytes += I.device->allocated_bytes() - before;
        I.device->check("Accel::commit (top-level BVH)");
        I.top_dirty = false;
    }
}

namespace {

/// Ticks this thread spent inside BVH queries since the last take_trace_ticks().
thread_local uint64_t t_trace_ticks = 0;

struct TraceScope {
    uint64_t start = cycle_now();
    ~TraceScope() { t_trace_ticks += cycle_now() - start; }
};

}  // namespace

uint64_t Accel::take_trace_ticks() {
    const uint64_t t = t_trace_ticks;
    t_trace_ticks = 0;
    return t;
}

uint64_t Accel::trace_ticks() { return t_trace_ticks; }

static void fill_ray(RTCRay& r, const Ray& ray) {
    r.org_x = ray.o.x; r.org_y = ray.o.y; r.org_z = ray.o.z;
    r.dir_x = ray.d.x; r.dir_y = ray.d.y; r.dir_z = ray.d.z;
    r.tnear = ray.tnear;
    r.tfar = ray.tfar;
    r.time = ray.time;
    r.mask = 0xFFFFFFFFu;
    r.id = k_invalid_id;  // the light proxy an occlusion ray skips (none)
    r.flags = 0;
}

namespace {

/// A query's answer as a Hit: a triangle of an instance, a light proxy (no instance) or
/// nothing; `lights`: the query tested the proxies.
inline Hit make_hit(bool lights, unsigned geom_id, unsigned inst_id, unsigned prim_id, float tfar, float u,
                    float v) {
    Hit h;
    if (lights) h.light = k_no_light_hit;
    if (geom_id == RTC_INVALID_GEOMETRY_ID) return h;
    h.t = tfar;
    if (inst_id == RTC_INVALID_GEOMETRY_ID) {  // the proxies' geometry (top level)
        h.light = prim_id;
        return h;
    }
    h.u = u;
    h.v = v;
    h.prim_id = prim_id;
    h.instance_id = inst_id - k_first_instance_geom_id;
    return h;
}

}  // namespace

Hit Accel::intersect(const Ray& ray, bool lights) const {
    const TraceScope timer;
    QueryContext qc(lights);
    RTCRayHit rh;
    fill_ray(rh.ray, ray);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(m_impl->top, &qc.ctx, &rh);
    return make_hit(lights, rh.hit.geomID, rh.hit.instID[0], rh.hit.primID, rh.ray.tfar, rh.hit.u, rh.hit.v);
}

bool Accel::occluded(const Ray& ray, bool lights, uint32_t skip_light) const {
    const TraceScope timer;
    QueryContext qc(lights);
    RTCRay r;
    fill_ray(r, ray);
    r.id = skip_light;
    rtcOccluded1(m_impl->top, &qc.ctx, &r);
    return r.tfar < 0.f;  // Embree sets tfar = -inf on a hit
}

namespace {

template <int N, typename RayHitN>
void fill_packet(RayHitN& p, const int* valid, const Ray* rays, int* mask) {
    for (int i = 0; i < N; ++i) {
        mask[i] = valid[i] ? -1 : 0;
        const Ray& r = rays[i];
        p.ray.org_x[i] = r.o.x; p.ray.org_y[i] = r.o.y; p.ray.org_z[i] = r.o.z;
        p.ray.dir_x[i] = r.d.x; p.ray.dir_y[i] = r.d.y; p.ray.dir_z[i] = r.d.z;
        p.ray.tnear[i] = r.tnear;
        p.ray.tfar[i] = r.tfar;
        p.ray.time[i] = r.time;
        p.ray.mask[i] = 0xFFFFFFFFu;
        p.ray.id[i] = k_invalid_id;
        p.ray.flags[i] = 0;
        p.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
        p.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
    }
}

template <int N, typename RayHitN>
void read_packet(const RayHitN& p, const int* mask, Hit* hits) {
    for (int i = 0; i < N; ++i) {
        hits[i] = mask[i] ? make_hit(false, p.hit.geomID[i], p.hit.instID[0][i], p.hit.primID[i], p.ray.tfar[i],
                                     p.hit.u[i], p.hit.v[i])
                          : Hit();
    }
}

/// Lane i of an Embree ray packet from `r` (every ray mask bit, no light proxy skipped,
/// no flags).
template <typename RayN>
inline void set_ray_lane(RayN& p, int i, const Ray& r) {
    p.org_x[i] = r.o.x; p.org_y[i] = r.o.y; p.org_z[i] = r.o.z;
    p.dir_x[i] = r.d.x; p.dir_y[i] = r.d.y; p.dir_z[i] = r.d.z;
    p.tnear[i] = r.tnear;
    p.tfar[i] = r.tfar;
    p.time[i] = r.time;
    p.mask[i] = 0xFFFFFFFFu;
    p.id[i] = k_invalid_id;
    p.flags[i] = 0;
}

template <int N, typename RayN>
void fill_ray_packet(RayN& p, const int* valid, const Ray* rays, int* mask) {
    for (int i = 0; i < N; ++i) {
        mask[i] = valid[i] ? -1 : 0;
        set_ray_lane(p, i, rays[i]);
    }
}

}  // namespace

void Accel::intersect_packet(int width, const int* valid, const Ray* rays, Hit* hits,
                             bool coherent) const {
    const TraceScope timer;
    QueryContext qc(false, coherent);
    RTCIntersectContext& ctx = qc.ctx;
    alignas(64) int mask[16];
    switch (width) {
        case 4: {
            RTCRayHit4 p;
            fill_packet<4>(p, valid, rays, mask);
            rtcIntersect4(mask, m_impl->top, &ctx, &p);
            read_packet<4>(p, mask, hits);
            break;
        }
        case 8: {
            RTCRayHit8 p;
            fill_packet<8>(p, valid, rays, mask);
            rtcIntersect8(mask, m_impl->top, &ctx, &p);
            read_packet<8>(p, mask, hits);
            break;
        }
        case 16: {
            RTCRayHit16 p;
            fill_packet<16>(p, valid, rays, mask);
            rtcIntersect16(mask, m_impl->top, &ctx, &p);
            read_packet<16>(p, mask, hits);
            break;
        }
        default: CMLT_THROW(std::invalid_argument, "packet width must be 4, 8 or 16, got " << width);
    }
}

void Accel::occluded_packet(int width, const int* valid, const Ray* rays, bool* occluded,
                            bool coherent) const {
    const TraceScope timer;
    QueryContext qc(false, coherent);
    RTCIntersectContext& ctx = qc.ctx;
    alignas(64) int mask[16];
    switch (width) {
        case 4: {
            RTCRay4 p;
            fill_ray_packet<4>(p, valid, rays, mask);
            rtcOccluded4(mask, m_impl->top, &ctx, &p);
            for (int i = 0; i < 4; ++i) occluded[i] = mask[i] && p.tfar[i] < 0.f;
            break;
        }
        case 8: {
            RTCRay8 p;
            fill_ray_packet<8>(p, valid, rays, mask);
            rtcOccluded8(mask, m_impl->top, &ctx, &p);
            for (int i = 0; i < 8; ++i) occluded[i] = mask[i] && p.tfar[i] < 0.f;
            break;
        }
        case 16: {
            RTCRay16 p;
            fill_ray_packet<16>(p, valid, rays, mask);
            rtcOccluded16(mask, m_impl->top, &ctx, &p);
            for (int i = 0; i < 16; ++i) occluded[i] = mask[i] && p.tfar[i] < 0.f;
            break;
        }
        default: CMLT_THROW(std::invalid_argument, "packet width must be 4, 8 or 16, got " << width);
    }
}

namespace {

/// Width of the packet for `left` pending lanes: the smallest native one holding them.
inline int packet_width(size_t left, int max_width) {
    return std::min(left <= 4 ? 4 : (left <= 8 ? 8 : 16), max_width);
}

template <int N, typename RayN>
inline void gather_rays(RayN& p, const Ray* rays, const uint32_t* lanes, size_t k, int* mask) {
    for (int i = 0; i < N; ++i) {
        // inactive lanes repeat the first ray (Embree reads every lane)
        mask[i] = size_t(i) < k ? -1 : 0;
        set_ray_lane(p, i, rays[lanes[size_t(i) < k ? size_t(i) : 0]]);
    }
}

template <int N, typename RayHitN>
inline void intersect_n(RTCScene scene, const Ray* rays, const uint32_t* lanes, size_t k, Hit* hits, bool lights) {
    alignas(64) int mask[N];
    RayHitN p;
    gather_rays<N>(p.ray, rays, lanes, k, mask);
    for (int i = 0; i < N; ++i) {
        p.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
        p.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
    }
    QueryContext qc(lights);
    RTCIntersectContext& ctx = qc.ctx;
    if constexpr (N == 4) rtcIntersect4(mask, scene, &ctx, &p);
    else if constexpr (N == 8) rtcIntersect8(mask, scene, &ctx, &p);
    else rtcIntersect16(mask, scene, &ctx, &p);
    for (size_t i = 0; i < k; ++i)
        hits[lanes[i]] =
            make_hit(lights, p.hit.geomID[i], p.hit.instID[0][i], p.hit.primID[i], p.ray.tfar[i], p.hit.u[i], p.hit.v[i]);
}

template <int N, typename RayN>
inline void occluded_n(RTCScene scene, const Ray* rays, const uint32_t* lanes, size_t k, uint8_t* occluded,
                       bool lights, const uint32_t* skip) {
    alignas(64) int mask[N];
    RayN p;
    gather_rays<N>(p, rays, lanes, k, mask);
    if (skip)
        for (size_t i = 0; i < k; ++i) p.id[i] = skip[lanes[i]];
    QueryContext qc(lights);
    RTCIntersectContext& ctx = qc.ctx;
    if constexpr (N == 4) rtcOccluded4(mask, scene, &ctx, &p);
    else if constexpr (N == 8) rtcOccluded8(mask, scene, &ctx, &p);
    else rtcOccluded16(mask, scene, &ctx, &p);
    for (size_t i = 0; i < k; ++i) occluded[lanes[i]] = p.tfar[i] < 0.f;
}

/// Lanes [0, n) in packets of the widths packet_width picks (at most max_width; one at a
/// time below 4 or when fewer than min_lanes are left): one(i) traces lane i alone,
/// packet(width, i, k) the k lanes from i (timed as trace). Returns the packets traced.
template <class One, class Packet>
size_t split_packets(size_t n, int max_width, size_t min_lanes, One&& one, Packet&& packet) {
    size_t packets = 0;
    for (size_t p = 0; p < n;) {
        const size_t left = n - p;
        const int width = max_width >= 4 ? packet_width(left, max_width) : 1;
        const size_t k = std::min(left, size_t(width));
        if (width == 1 || k < min_lanes) {
            one(p);
            ++p;
            continue;
        }
        const TraceScope timer;
        packet(width, p, k);
        ++packets;
        p += k;
    }
    return packets;
}

}  // namespace

size_t Accel::intersect_lanes(const Ray* rays, const uint32_t* lanes, size_t n, Hit* hits, int max_width,
                              size_t min_lanes, bool lights) const {
    return split_packets(
        n, max_width, min_lanes, [&](size_t p) { hits[lanes[p]] = intersect(rays[lanes[p]], lights); },
        [&](int width, size_t p, size_t k) {
            if (width == 4) intersect_n<4, RTCRayHit4>(m_impl->top, rays, lanes + p, k, hits, lights);
            else if (width == 8) intersect_n<8, RTCRayHit8>(m_impl->top, rays, lanes + p, k, hits, lights);
            else intersect_n<16, RTCRayHit16>(m_impl->top, rays, lanes + p, k, hits, lights);
        });
}

size_t Accel::occluded_lanes(const Ray* rays, const uint32_t* lanes, size_t n, uint8_t* occluded, int max_width,
                             size_t min_lanes, bool lights, const uint32_t* skip_lights) const {
    return split_packets(
        n, max_width, min_lanes,
        [&](size_t p) {
            const uint32_t l = lanes[p];
            occluded[l] = this->occluded(rays[l], lights, skip_lights ? skip_lights[l] : k_invalid_id);
        },
        [&](int width, size_t p, size_t k) {
            const uint32_t* lp = lanes + p;
            if (width == 4) occluded_n<4, RTCRay4>(m_impl->top, rays, lp, k, occluded, lights, skip_lights);
            else if (width == 8) occluded_n<8, RTCRay8>(m_impl->top, rays, lp, k, occluded, lights, skip_lights);
            else occluded_n<16, RTCRay16>(m_impl->top, rays, lp, k, occluded, lights, skip_lights);
        });
}

int Accel::max_packet_width() {
    auto dev = EmbreeDevice::get();
    RTCDevice d = dev->handle();
    if (rtcGetDeviceProperty(d, RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED)) return 16;
    if (rtcGetDeviceProperty(d, RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED)) return 8;
    if (rtcGetDeviceProperty(d, RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED)) return 4;
    return 1;
}

}  // namespace cmlt
