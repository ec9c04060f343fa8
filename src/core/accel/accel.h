#pragma once
/// \file Ray-query acceleration over triangle meshes (Embree 3).
///
/// The only module that includes <embree3/rtcore.h> is accel/*.cpp; this header is
/// Embree-free. Layout follows OpenUSD's hdEmbree: each mesh owns an RTCScene with one
/// triangle geometry; every placement of a mesh is an RTC_GEOMETRY_TYPE_INSTANCE in the
/// top-level scene, so a rigid motion only rewrites an instance transform and a
/// deformation refits one mesh BVH.
///
/// Vertex and index buffers are shared with the caller (rtcSetSharedGeometryBuffer,
/// zero copy). The vertex buffer must be readable for 4 bytes past the last vertex
/// (the Python side pads one spare row, see cmlt/scene.py `padded_points`).
#include "math/mat4.h"
#include "math/ray.h"

#include <cstddef>
#include <cstdint>
#include <memory>

namespace cmlt {

constexpr uint32_t k_invalid_id = 0xFFFFFFFFu;

/// Meshes with at least this many triangles get a compact BVH (accel.cpp: less memory,
/// slower queries); smaller ones the default, faster leaves.
constexpr size_t k_compact_bvh_triangles = size_t(1) << 16;

/// Result of a closest-hit query. Barycentrics (u, v) weight vertices 1 and 2.
struct Hit {
    float t = k_infinity;
    float u = 0.f, v = 0.f;
    uint32_t prim_id = k_invalid_id;
    uint32_t instance_id = k_invalid_id;
    bool valid() const { return instance_id != k_invalid_id; }
};

class Accel {
public:
    Accel();
    ~Accel();
    Accel(const Accel&) = delete;
    Accel& operator=(const Accel&) = delete;

    /// Register a triangle mesh. `points` is float32 (n_points, 3) (+4 readable bytes),
    /// `indices` uint32 (n_tris, 3). Returns the mesh id (0, 1, ...).
    uint32_t add_mesh(const float* points, size_t n_points, const uint32_t* indices, size_t n_tris);
    /// Point the mesh at new vertex data (same count) and rebuild/refit its BVH at commit.
    void update_mesh_points(uint32_t mesh_id, const float* points);
    /// Place a mesh. Returns the instance id (0, 1, ...), the Embree instance geometry id.
    uint32_t add_instance(uint32_t mesh_id, const Mat4& object_to_world);
    void set_instance_transform(uint32_t instance_id, const Mat4& object_to_world);
    /// Motion blur: `n_steps` >= 2 transforms evenly spaced over the shutter (ray time
    /// 0 .. 1); Embree interpolates the 3x4 matrices linearly between steps
    /// (rtcSetGeometryTimeStepCount + rtcSetGeometryTransform per step).
    /// set_instance_transform returns the instance to one time step.
    void set_instance_motion(uint32_t instance_id, const Mat4* steps, uint32_t n_steps);
    /// Commit dirty meshes, then the top-level scene. Throws SceneError on Embree errors.
    void commit();

    size_t mesh_count() const;
    size_t instance_count() const;
    /// Bytes Embree holds for mesh `mesh_id` (its scene, geometry and BVH; not the shared
    /// vertex and index buffers), as its memory monitor counted them around the mesh's
    /// creation and commits. Exact while one thread at a time builds BVHs on the
    /// process's device (the renderer builds one scene at a time).
    size_t mesh_bvh_bytes(uint32_t mesh_id) const;
    /// The same for the top-level scene (instance geometries and their BVH).
    size_t top_level_bytes() const;

    /// Closest hit in (tnear, tfar).
    Hit intersect(const Ray& ray) const;
    /// Any hit in (tnear, tfar).
    bool occluded(const Ray& ray) const;

    /// Packet queries (rtcIntersect4/8/16, rtcOccluded4/8/16). `width` is 4, 8 or 16;
    /// `valid[i]` != 0 marks active lanes; inactive lanes get an invalid Hit / false.
    /// `coherent` sets RTC_INTERSECT_CONTEXT_FLAG_COHERENT. Off by default: with it,
    /// Embree 3.13 (Debian 12) missed hits on flat instances (an emitter quad, a cut-out
    /// quad) for packets whose lanes start at different points — light-subpath bounces
    /// of one bundle — where rtcIntersect1 found them (test10b in
    /// tests/python/integrators/test_light_transport.py caught it; Accel.PacketOfLightSubpathBouncesFindsFlatInstances
    /// replays the packet). Without it packets and single rays agree.
    void intersect_packet(int width, const int* valid, const Ray* rays, Hit* hits,
                          bool coherent = false) const;
    void occluded_packet(int width, const int* valid, const Ray* rays, bool* occluded,
                         bool coherent = false) const;

    /// Queries for lanes of a batch: rays[lanes[i]] for i < n, answered in packets of up
    /// to `max_width` lanes (the smallest native width holding the lanes left; fewer
    /// than `min_lanes` left go one by one), written to hits[lanes[i]] /
    /// occluded[lanes[i]]. Returns the number of packet queries made. Hits may differ
    /// from intersect()'s in the last ulp (Embree's packet and single-ray kernels).
    size_t intersect_lanes(const Ray* rays, const uint32_t* lanes, size_t n, Hit* hits, int max_width,
                           size_t min_lanes = 4) const;
    size_t occluded_lanes(const Ray* rays, const uint32_t* lanes, size_t n, uint8_t* occluded, int max_width,
                          size_t min_lanes = 4) const;

    /// Ticks (util/cycle_clock.h) the calling thread spent in the queries above since
    /// the previous call; resets the thread's count. For the trace / shade split of
    /// the render stats.
    static uint64_t take_trace_ticks();
    /// The calling thread's query ticks since its last take_trace_ticks(), without
    /// resetting them (to time a part of a task, as coherent MLT's bundles).
    static uint64_t trace_ticks();

    /// Largest packet width with native support in this Embree build on this CPU (4, 8 or 16).
    static int max_packet_width();

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

}  // namespace cmlt
