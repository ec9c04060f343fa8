#pragma once
/// \file Warps from [0,1)^n to domains, with their pdfs.
///
/// Pdfs are per solid angle for directions and per area for points, unless noted.
#include "math/safe_math.h"
#include "math/sincos.h"
#include "math/vec.h"

namespace cmlt {

// The warps with a sine and cosine are inline: the SIMD lanes of the path batches inline
// them too, and get the same floats (math/sincos.h).

/// Concentric map of Shirley & Chiu, unit disk, pdf 1/pi.
inline Vec2 square_to_uniform_disk_concentric(const Vec2& u) { return concentric_disk(u.x, u.y); }
inline float square_to_uniform_disk_concentric_pdf(const Vec2& p) {
    return (p.x * p.x + p.y * p.y) <= 1.f ? k_inv_pi : 0.f;
}

/// Cosine-weighted hemisphere about +z, pdf cos(theta)/pi.
inline Vec3 square_to_cosine_hemisphere(const Vec2& u) {
    const Vec2 d = square_to_uniform_disk_concentric(u);
    return {d.x, d.y, safe_sqrt(1.f - d.x * d.x - d.y * d.y)};
}
inline float square_to_cosine_hemisphere_pdf(const Vec3& w) { return w.z > 0.f ? w.z * k_inv_pi : 0.f; }

/// Uniform sphere, pdf 1/(4 pi).
inline Vec3 square_to_uniform_sphere(const Vec2& u) {
    const float z = 1.f - 2.f * u.x, r = safe_sqrt(1.f - z * z);
    float s, c;
    sincos_turn(u.y, &s, &c);  // φ = 2π u.y
    return {r * c, r * s, z};
}
inline float square_to_uniform_sphere_pdf(const Vec3&) { return k_inv_4pi; }

/// Uniform hemisphere about +z, pdf 1/(2 pi).
inline Vec3 square_to_uniform_hemisphere(const Vec2& u) {
    const float z = u.x, r = safe_sqrt(1.f - z * z);
    float s, c;
    sincos_turn(u.y, &s, &c);  // φ = 2π u.y
    return {r * c, r * s, z};
}
inline float square_to_uniform_hemisphere_pdf(const Vec3& w) { return w.z >= 0.f ? k_inv_2pi : 0.f; }

/// Uniform cone about +z with half-angle acos(cos_max), pdf 1/(2 pi (1 - cos_max)).
/// `one_minus_cos_max` is passed separately for accuracy with tiny cones.
inline Vec3 square_to_uniform_cone(const Vec2& u, float one_minus_cos_max) {
    // 1 - cos(theta) uniform in [0, one_minus_cos_max]; sin from (1-cos)(1+cos).
    const float omc = u.x * one_minus_cos_max;
    const float sin_theta = safe_sqrt(omc * (2.f - omc));
    float s, c;
    sincos_turn(u.y, &s, &c);  // φ = 2π u.y
    return {sin_theta * c, sin_theta * s, 1.f - omc};
}
float square_to_uniform_cone_pdf(const Vec3& w, float one_minus_cos_max);

/// Uniform barycentrics (b1, b2) of a triangle (Heitz 2019, low-distortion map);
/// b0 = 1 - b1 - b2. Pdf per area is 1/area.
Vec2 square_to_uniform_triangle(const Vec2& u);

/// 1-minus-cosine of the half-angle of the cone subtended by a sphere of radius r seen
/// from distance d > r; computed without cancellation.
float sphere_cone_one_minus_cos(float r, float d);

}  // namespace cmlt
