#pragma once
/// \file What coordinates the renderer can trace, checked at commit.
///
/// Embree asserts (aborts the process) on a ray whose origin or direction has a
/// component beyond about 1.8e18 (its FLT_LARGE), in world space or in an instance's
/// object space, where it moves the ray by the inverse transform. Long before that a
/// float scene has no precision left (at 1e15 neighbouring floats are 6.7e7 apart). So
/// a scene is refused, with an error naming the prim, when
/// * a mesh point (object space), an instance's world-space bounds, a light's position
///   and extent or the camera lies beyond k_max_coordinate, or
/// * an instance transform is so degenerate (a scale of 1e-30 on one axis) that it maps
///   a point of the scene's world-space extent, or a unit direction, beyond
///   k_max_object_coordinate in object space.
#include "math/mat4.h"

namespace cmlt {

constexpr double k_max_coordinate = 1e15;
constexpr double k_max_object_coordinate = 1e17;

/// Largest |component| of the box [lo, hi] (NaN counts as infinite).
double max_abs(const Vec3& lo, const Vec3& hi);

/// Largest |component| of m * [p, 1] over the points with every |p_i| <= extent: with
/// an instance's inverse and the scene's extent (at least 1, for unit directions) the
/// object-space reach of the scene's rays; with a light's transform and its size the
/// reach of the points it emits from.
double affine_reach(const Mat4& m, double extent);

}  // namespace cmlt
