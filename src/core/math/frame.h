#pragma once
/// \file Orthonormal basis; local z is the normal.
#include "math/vec.h"

#include <cmath>

namespace cmlt {

/// Orthonormal frame (s, t, n). `to_local` / `to_world` convert directions.
/// Built with Duff et al. 2017, "Building an Orthonormal Basis, Revisited".
struct Frame {
    Vec3 s{1, 0, 0}, t{0, 1, 0}, n{0, 0, 1};

    Frame() = default;
    explicit Frame(const Vec3& normal) : n(normal) {
        float sign = std::copysign(1.f, n.z);
        float a = -1.f / (sign + n.z);
        float b = n.x * n.y * a;
        s = Vec3(1.f + sign * n.x * n.x * a, sign * b, -sign * n.x);
        t = Vec3(b, sign + n.y * n.y * a, -n.y);
    }
    Vec3 to_local(const Vec3& v) const { return {dot(v, s), dot(v, t), dot(v, n)}; }
    Vec3 to_world(const Vec3& v) const { return s * v.x + t * v.y + n * v.z; }

    static float cos_theta(const Vec3& w) { return w.z; }
    static float abs_cos_theta(const Vec3& w) { return std::fabs(w.z); }
};

}  // namespace cmlt
