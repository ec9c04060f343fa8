#pragma once
/// \file Ray-query acceleration over triangle meshes (Embree 3).
///
/// The only module that includes <embree3/rtcore.h> is accel/*.cpp; this header is
/// Embree-free. Layout follows OpenUSD's hdEmbree: each mesh owns an RTCScene with one
/// triangle geometry; every placement of a mesh is an RTC_GEOMETRY_TYPE_INSTANCE in the
/// top-level scene, so a rigid motion only rewrites an instance transform and a
/// deformation refits one mesh BVH.
///
/// Beside the instances, the top level can hold light proxies (set_light_proxies): one
/// user geometry whose primitives are the scene's analytic area lights, tested by the
/// caller's callbacks, seen only by queries that ask for them.
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

/// Hit::light of a query that did not test the light proxies.
constexpr uint32_t k_lights_untested = 0xFFFFFFFFu;
/// Hit::light of a query that tested them and found none nearer than the mesh hit (if any).
constexpr uint32_t k_no_light_hit = 0xFFFFFFFEu;

/// Result of a closest-hit query. Barycentrics (u, v) weight vertices 1 and 2.
/// `valid()` means a mesh triangle is the nearest hit; a query with the light proxies
/// (Accel::set_light_proxies) sets `light`: the proxy nearer than every triangle (t is
/// its distance, valid() false), or k_no_light_hit.
struct Hit {
    float t = k_infinity;
    float u = 0.f, v = 0.f;
    uint32_t prim_id = k_invalid_id;
    uint32_t instance_id = k_invalid_id;
    uint32_t light = k_lights_untested;
    bool valid() const { return instance_id != k_invalid_id; }
    bool light_hit() const { return light < k_no_light_hit; }
};

/// Shapes the BVH holds beside the meshes (analytic area lights, Scene::build_lights):
/// primitive k has a world bounding box given to Accel::set_light_proxies, and Embree
/// calls `intersect(k, ...)` for rays that enter that box, so the one traversal of a
/// query finds the nearest of the triangles and the proxies.
class LightProxies {
public:
    virtual ~LightProxies() = default;
    /// Does `ray` hit proxy k within (ray.tnear, ray.tfar)? Then its distance in *t.
    virtual bool intersect(uint32_t k, const Ray& ray, float* t) const = 0;
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

    /// The light proxies: `n` primitives, boxes[6k .. 6k+6) proxy k's world box (lower
    /// x, y, z, upper x, y, z), `proxies` (kept by the caller, alive while queries run)
    /// their test. n = 0 removes them. Takes effect at the next commit(); a call with the
    /// same boxes and object changes nothing. The proxies are seen only by queries that
    /// ask for them (`lights`); every other query answers for the meshes alone.
    void set_light_proxies(const LightProxies* proxies, const float* boxes, size_t n);

    /// Closest hit in (tnear, tfar); with `lights`, of the meshes and light proxies.
    Hit intersect(const Ray& ray, bool lights = false) const;
    /// Any hit in (tnear, tfar); with `lights`, light proxies block too, except proxy
    /// `skip_light` (k_invalid_id: none).
    bool occluded(const Ray& ray, bool lights = false, uint32_t skip_light = k_invalid_id) const;

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
    /// With `lights`, the light proxies too (as intersect(ray, true)); `skip_lights`
    /// (indexed like rays, null: none skipped) the proxy each occlusion ray does not test.
    size_t intersect_lanes(const Ray* rays, const uint32_t* lanes, size_t n, Hit* hits, int max_width,
                           size_t min_lanes = 4, bool lights = false) const;
    size_t occluded_lanes(const Ray* rays, const uint32_t* lanes, size_t n, uint8_t* occluded, int max_width,
                          size_t min_lanes = 4, bool lights = false, const uint32_t* skip_lights = nullptr) const;

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
