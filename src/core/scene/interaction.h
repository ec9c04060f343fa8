#pragma once
/// \file Surface interaction and robust ray spawning.
///
/// Spawned rays start at the hit point pushed along the geometric normal, to the side
/// of the new direction, by `k_offset_rel * error_scale`, where `error_scale` is the
/// largest absolute world coordinate of the hit triangle's vertices. Position error of
/// the interpolated/transformed hit point is a few ulps of that magnitude, so the offset
/// works at any scene scale (1e-6 m or 1e6 m); rays then use tnear = 0.
#include "math/ray.h"
#include "math/vec.h"

#include <cstdint>

namespace cmlt {

/// Relative offset: 64 ulps of float (2^-18). The hit point is an affine combination
/// of the world-space vertices, so its distance from the triangle's plane is a few ulps
/// of `error_scale`; Embree's float instance transform adds about one more. A larger
/// offset biases MIS (BSDF rays start visibly closer to lights than the shading point:
/// 2^-13 gave +0.25% on a 20 m plane lit from 1 m).
constexpr float k_offset_rel = 0x1p-18f;
/// Shadow rays stop this fraction short of their (already offset) target.
constexpr float k_shadow_epsilon = 1e-4f;

/// Most per-vertex primvar columns a mesh carries (MeshData::primvars): enough for a
/// displayColor (3) + displayOpacity (1) and one more colour and scalar; each column costs
/// a float in every SurfaceInteraction.
constexpr int k_max_primvar_columns = 8;

inline Vec3 offset_ray_origin(const Vec3& p, const Vec3& ng, float error_scale, const Vec3& w) {
    Vec3 off = ng * (k_offset_rel * error_scale);
    return dot(w, ng) < 0.f ? p - off : p + off;
}

/// Where a shadow ray toward a sampled light point `p_light` (reached along `wi`) aims:
/// the point itself on a light without a surface normal, else `p_light` offset off the
/// light's surface toward the ray, so the ray does not hit the light itself.
inline Vec3 shadow_target(const Vec3& p_light, const Vec3& n_light, float error_scale, const Vec3& wi) {
    return is_black(n_light) ? p_light : offset_ray_origin(p_light, n_light, error_scale, -wi);
}

/// Error scale of a point given by itself (analytic shapes).
inline float point_error_scale(const Vec3& p) { return max_component(vabs(p)); }

/// A point on a surface as rays leave it: position, geometric normal, offset scale,
/// shutter time; what spawning a ray needs.
struct SurfacePoint {
    Vec3 p;            ///< world position (from barycentrics, not from the ray)
    Vec3 ng;           ///< unit geometric normal (CCW winding in world space)
    float error_scale = 0.f;
    float time = 0.f;  ///< shutter time of the ray that hit (spawned rays inherit it)

    Ray spawn_ray(const Vec3& d) const {
        Ray r(offset_ray_origin(p, ng, error_scale, d), d, 0.f, k_infinity);
        r.time = time;
        return r;
    }
    /// Shadow ray toward `target` (already offset if it lies on a surface). The ray
    /// direction is unnormalised: t runs over [0, 1 - eps].
    Ray spawn_ray_to(const Vec3& target) const {
        Vec3 o = offset_ray_origin(p, ng, error_scale, target - p);
        Ray r(o, target - o, 0.f, 1.f - k_shadow_epsilon);
        r.time = time;
        return r;
    }
};

struct SurfaceInteraction : SurfacePoint {
    Vec3 ns;           ///< unit shading normal, flipped to the side of ng
    Vec2 uv;
    Vec3 dpdu;         ///< world dp/du from the triangle's uvs (zero without uvs / degenerate)
    Vec3 wo;           ///< unit direction toward the ray origin
    float t = 0.f;
    uint32_t instance_id = 0;
    uint32_t mesh_id = 0;
    uint32_t prim_id = 0;
    uint32_t material_id = 0;
    /// The mesh's per-vertex primvar columns (MeshData::primvars) interpolated at the hit
    /// with its barycentrics; the first `n_primvars` are set (0 for a mesh without them).
    /// Material inputs read by a UsdPrimvarReader take their value from here.
    uint8_t n_primvars = 0;
    float primvars[k_max_primvar_columns] = {};
};

}  // namespace cmlt
