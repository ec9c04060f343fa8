#pragma once
/// \file Warps from [0,1)^n to domains, with their pdfs.
///
/// Pdfs are per solid angle for directions and per area for points, unless noted.
#include "math/safe_math.h"
#include "math/vec.h"

namespace cmlt {

/// Concentric map of Shirley & Chiu, unit disk, pdf 1/pi.
Vec2 square_to_uniform_disk_concentric(const Vec2& u);
inline float square_to_uniform_disk_concentric_pdf(const Vec2& p) {
    return (p.x * p.x + p.y * p.y) <= 1.f ? k_inv_pi : 0.f;
}

/// Cosine-weighted hemisphere about +z, pdf cos(theta)/pi.
Vec3 square_to_cosine_hemisphere(const Vec2& u);
inline float square_to_cosine_hemisphere_pdf(const Vec3& w) { return w.z > 0.f ? w.z * k_inv_pi : 0.f; }

/// Uniform sphere, pdf 1/(4 pi).
Vec3 square_to_uniform_sphere(const Vec2& u);
inline float square_to_uniform_sphere_pdf(const Vec3&) { return k_inv_4pi; }

/// Uniform hemisphere about +z, pdf 1/(2 pi).
Vec3 square_to_uniform_hemisphere(const Vec2& u);
inline float square_to_uniform_hemisphere_pdf(const Vec3& w) { return w.z >= 0.f ? k_inv_2pi : 0.f; }

/// Uniform cone about +z with half-angle acos(cos_max), pdf 1/(2 pi (1 - cos_max)).
/// `one_minus_cos_max` is passed separately for accuracy with tiny cones.
Vec3 square_to_uniform_cone(const Vec2& u, float one_minus_cos_max);
float square_to_uniform_cone_pdf(const Vec3& w, float one_minus_cos_max);

/// Uniform barycentrics (b1, b2) of a triangle (Heitz 2019, low-distortion map);
/// b0 = 1 - b1 - b2. Pdf per area is 1/area.
Vec2 square_to_uniform_triangle(const Vec2& u);

/// 1-minus-cosine of the half-angle of the cone subtended by a sphere of radius r seen
/// from distance d > r; computed without cancellation.
float sphere_cone_one_minus_cos(float r, float d);

}  // namespace cmlt
