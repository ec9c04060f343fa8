#pragma once
/// \file Ray with a parametric range [tnear, tfar].
#include "math/vec.h"

#include <limits>

namespace cmlt {

constexpr float k_infinity = std::numeric_limits<float>::infinity();

struct Ray {
    Vec3 o;
    Vec3 d;
    float tnear = 0.f;
    float tfar = k_infinity;
    /// Time within the camera shutter, in [0, 1] (0 = shutter open). Only motion-blurred
    /// geometry looks at it; rays spawned from a hit inherit it (SurfaceInteraction::time).
    float time = 0.f;

    Ray() = default;
    Ray(const Vec3& o_, const Vec3& d_, float tnear_ = 0.f, float tfar_ = k_infinity)
        : o(o_), d(d_), tnear(tnear_), tfar(tfar_) {}
    Vec3 at(float t) const { return o + d * t; }
};

}  // namespace cmlt
