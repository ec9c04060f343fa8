#pragma once
/// \file 4x4 double matrix, column-vector convention: p' = M * [p, 1].
///
/// m[r][c] is row r, column c; the translation is column 3 (m[0..2][3]).
/// This is the transpose of USD's Gf.Matrix4d (row-vector convention).
#include "math/vec.h"

namespace cmlt {

struct Mat4 {
    double m[4][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}};

    static Mat4 identity() { return Mat4(); }
    static Mat4 from_row_major(const double* a);  ///< a[r*4+c]
    static Mat4 translate(double x, double y, double z);
    static Mat4 scale(double x, double y, double z);
    /// Rotation about a unit axis by `deg` degrees (right-handed).
    static Mat4 rotate(double deg, double ax, double ay, double az);

    Mat4 operator*(const Mat4& b) const;
    Mat4 transpose() const;
    /// Inverse by cofactors; `ok` is false (and identity returned) when singular.
    Mat4 inverse(bool* ok = nullptr) const;
    double determinant() const;
    bool is_finite() const;
    /// Affine: bottom row is (0, 0, 0, 1).
    bool is_affine() const;

    Vec3 transform_point(const Vec3& p) const;
    /// transform_point of an affine matrix (is_affine(), as every Transform::m): without
    /// the homogeneous row, which is exactly 1 there for a finite p, so the same floats.
    Vec3 transform_affine_point(const Vec3& p) const;
    Vec3 transform_vector(const Vec3& v) const;
    /// Transform a normal with *this* being the inverse-transpose (the normal matrix).
    Vec3 transform_normal(const Vec3& n) const { return transform_vector(n); }
};

// Inline: every hit places its triangle with these (scene/scene_queries.cpp).
inline Vec3 Mat4::transform_point(const Vec3& p) const {
    double x = p.x, y = p.y, z = p.z;
    double rx = m[0][0] * x + m[0][1] * y + m[0][2] * z + m[0][3];
    double ry = m[1][0] * x + m[1][1] * y + m[1][2] * z + m[1][3];
    double rz = m[2][0] * x + m[2][1] * y + m[2][2] * z + m[2][3];
    double rw = m[3][0] * x + m[3][1] * y + m[3][2] * z + m[3][3];
    if (rw != 1.0 && rw != 0.0) { rx /= rw; ry /= rw; rz /= rw; }
    return {float(rx), float(ry), float(rz)};
}

inline Vec3 Mat4::transform_affine_point(const Vec3& p) const {
    double x = p.x, y = p.y, z = p.z;
    return {float(m[0][0] * x + m[0][1] * y + m[0][2] * z + m[0][3]),
            float(m[1][0] * x + m[1][1] * y + m[1][2] * z + m[1][3]),
            float(m[2][0] * x + m[2][1] * y + m[2][2] * z + m[2][3])};
}

inline Vec3 Mat4::transform_vector(const Vec3& v) const {
    double x = v.x, y = v.y, z = v.z;
    return {float(m[0][0] * x + m[0][1] * y + m[0][2] * z),
            float(m[1][0] * x + m[1][1] * y + m[1][2] * z),
            float(m[2][0] * x + m[2][1] * y + m[2][2] * z)};
}

/// A transform with its inverse and normal matrix (inverse transpose).
struct Transform {
    Mat4 m, inv, normal;
    Transform() = default;
    /// Throws SceneError if singular or not finite (`what` names the object).
    Transform(const Mat4& mat, const char* what);
};

}  // namespace cmlt
