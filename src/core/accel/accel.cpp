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
        for (auto& i : instances) rtcReleaseGeometry(i.geom);
        for (auto& m : meshes) {
            rtcReleaseGeometry(m.geom);
            rtcReleaseScene(m.scene);
        }
        if (top) rtcReleaseScene(top);
    }
};

Accel::Accel() : m_impl(new Impl()) {}
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
    rtcAttachGeometryByID(I.top, inst.geom, id);
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
    r.id = 0;
    r.flags = 0;
}

Hit Accel::intersect(const Ray& ray) const {
    const TraceScope timer;
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRayHit rh;
    fill_ray(rh.ray, ray);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(m_impl->top, &ctx, &rh);
    Hit h;
    if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
        h.t = rh.ray.tfar;
        h.u = rh.hit.u;
        h.v = rh.hit.v;
        h.prim_id = rh.hit.primID;
        h.instance_id = rh.hit.instID[0];
    }
    return h;
}

bool Accel::occluded(const Ray& ray) const {
    const TraceScope timer;
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRay r;
    fill_ray(r, ray);
    rtcOccluded1(m_impl->top, &ctx, &r);
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
        p.ray.id[i] = unsigned(i);
        p.ray.flags[i] = 0;
        p.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
        p.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
    }
}

template <int N, typename RayHitN>
void read_packet(const RayHitN& p, const int* mask, Hit* hits) {
    for (int i = 0; i < N; ++i) {
        Hit h;
        if (mask[i] && p.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID) {
            h.t = p.ray.tfar[i];
            h.u = p.hit.u[i];
            h.v = p.hit.v[i];
            h.prim_id = p.hit.primID[i];
            h.instance_id = p.hit.instID[0][i];
        }
        hits[i] = h;
    }
}

/// Lane i of an Embree ray packet from `r` (every ray mask bit, id i, no flags).
template <typename RayN>
inline void set_ray_lane(RayN& p, int i, const Ray& r) {
    p.org_x[i] = r.o.x; p.org_y[i] = r.o.y; p.org_z[i] = r.o.z;
    p.dir_x[i] = r.d.x; p.dir_y[i] = r.d.y; p.dir_z[i] = r.d.z;
    p.tnear[i] = r.tnear;
    p.tfar[i] = r.tfar;
    p.time[i] = r.time;
    p.mask[i] = 0xFFFFFFFFu;
    p.id[i] = unsigned(i);
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
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    if (coherent) ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
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
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    if (coherent) ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
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
inline void intersect_n(RTCScene scene, const Ray* rays, const uint32_t* lanes, size_t k, Hit* hits) {
    alignas(64) int mask[N];
    RayHitN p;
    gather_rays<N>(p.ray, rays, lanes, k, mask);
    for (int i = 0; i < N; ++i) {
        p.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
        p.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
    }
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    if constexpr (N == 4) rtcIntersect4(mask, scene, &ctx, &p);
    else if constexpr (N == 8) rtcIntersect8(mask, scene, &ctx, &p);
    else rtcIntersect16(mask, scene, &ctx, &p);
    for (size_t i = 0; i < k; ++i) {
        Hit h;
        if (p.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID) {
            h.t = p.ray.tfar[i];
            h.u = p.hit.u[i];
            h.v = p.hit.v[i];
            h.prim_id = p.hit.primID[i];
            h.instance_id = p.hit.instID[0][i];
        }
        hits[lanes[i]] = h;
    }
}

template <int N, typename RayN>
inline void occluded_n(RTCScene scene, const Ray* rays, const uint32_t* lanes, size_t k, uint8_t* occluded) {
    alignas(64) int mask[N];
    RayN p;
    gather_rays<N>(p, rays, lanes, k, mask);
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
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
                              size_t min_lanes) const {
    return split_packets(
        n, max_width, min_lanes, [&](size_t p) { hits[lanes[p]] = intersect(rays[lanes[p]]); },
        [&](int width, size_t p, size_t k) {
            if (width == 4) intersect_n<4, RTCRayHit4>(m_impl->top, rays, lanes + p, k, hits);
            else if (width == 8) intersect_n<8, RTCRayHit8>(m_impl->top, rays, lanes + p, k, hits);
            else intersect_n<16, RTCRayHit16>(m_impl->top, rays, lanes + p, k, hits);
        });
}

size_t Accel::occluded_lanes(const Ray* rays, const uint32_t* lanes, size_t n, uint8_t* occluded, int max_width,
                             size_t min_lanes) const {
    return split_packets(
        n, max_width, min_lanes, [&](size_t p) { occluded[lanes[p]] = this->occluded(rays[lanes[p]]); },
        [&](int width, size_t p, size_t k) {
            if (width == 4) occluded_n<4, RTCRay4>(m_impl->top, rays, lanes + p, k, occluded);
            else if (width == 8) occluded_n<8, RTCRay8>(m_impl->top, rays, lanes + p, k, occluded);
            else occluded_n<16, RTCRay16>(m_impl->top, rays, lanes + p, k, occluded);
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
