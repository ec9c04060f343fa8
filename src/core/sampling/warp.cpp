#include "sampling/warp.h"

#include <cmath>

namespace cmlt {

Vec2 square_to_uniform_disk_concentric(const Vec2& u) {
    float x = 2.f * u.x - 1.f, y = 2.f * u.y - 1.f;
    if (x == 0.f && y == 0.f) return {0.f, 0.f};
    float r, theta;
    if (std::fabs(x) > std::fabs(y)) {
        r = x;
        theta = k_pi_over_4 * (y / x);
    } else {
        r = y;
        theta = k_pi_over_2 - k_pi_over_4 * (x / y);
    }
    return {r * std::cos(theta), r * std::sin(theta)};
}

Vec3 square_to_cosine_hemisphere(const Vec2& u) {
    Vec2 d = square_to_uniform_disk_concentric(u);
    float z = safe_sqrt(1.f - d.x * d.x - d.y * d.y);
    return {d.x, d.y, z};
}

Vec3 square_to_uniform_sphere(const Vec2& u) {
    float z = 1.f - 2.f * u.x;
    float r = safe_sqrt(1.f - z * z);
    float phi = 2.f * k_pi * u.y;
    return {r * std::cos(phi), r * std::sin(phi), z};
}

Vec3 square_to_uniform_hemisphere(const Vec2& u) {
    float z = u.x;
    float r = safe_sqrt(1.f - z * z);
    float phi = 2.f * k_pi * u.y;
    return {r * std::cos(phi), r * std::sin(phi), z};
}

Vec3 square_to_uniform_cone(const Vec2& u, float one_minus_cos_max) {
    // 1 - cos(theta) uniform in [0, one_minus_cos_max]; sin from (1-cos)(1+cos).
    float omc = u.x * one_minus_cos_max;
    float cos_theta = 1.f - omc;
    float sin_theta = safe_sqrt(omc * (2.f - omc));
    float phi = 2.f * k_pi * u.y;
    return {sin_theta * std::cos(phi), sin_theta * std::sin(phi), cos_theta};
}

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
