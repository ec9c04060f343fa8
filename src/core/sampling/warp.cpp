#include "sampling/warp.h"

#include <cmath>

namespace cmlt {

float square_to_uniform_cone_pdf(const Vec3& w, float one_minus_cos_max) {
    if (!(one_minus_cos_max > 0.f)) return 0.f;
    // Inside test on 1 - cos, robust for tiny cones: 1 - cos = (x^2+y^2)/(1+cos) for |w| = 1.
    if (w.z <= 0.f && one_minus_cos_max < 1.f) return 0.f;
    float omc = (w.x * w.x + w.y * w.y) / (1.f + std::max(w.z, -1.f + 1e-7f));
    if (w.z < 0.f) omc = 1.f - w.z;
    if (omc > one_minus_cos_max * (1.f + 1e-5f)) return 0.f;
    return 1.f / (2.f * k_pi * one_minus_cos_max);
}

Vec2 square_to_uniform_triangle(const Vec2& u) {
    float b0, b1;
    if (u.x < u.y) {
        b0 = u.x / 2.f;
        b1 = u.y - b0;
    } else {
        b1 = u.y / 2.f;
        b0 = u.x - b1;
    }
    return {b0, b1};
}

float sphere_cone_one_minus_cos(float r, float d) {
    // sin^2 = (r/d)^2; 1 - cos = sin^2 / (1 + cos).
    double s2 = double(r) * r / (double(d) * d);
    if (s2 >= 1.0) return 1.f;
    double c = std::sqrt(1.0 - s2);
    return float(s2 / (1.0 + c));
}

}  // namespace cmlt
