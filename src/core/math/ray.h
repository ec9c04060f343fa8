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

    Ray() = default;
    Ray(const Vec3& o_, const Vec3& d_, float tnear_ = 0.f, float tfar_ = k_infinity)
        : o(o_), d(d_), tnear(tnear_), tfar(tfar_) {}
    Vec3 at(float t) const { return o + d * t; }
};

}  // namespace cmlt
