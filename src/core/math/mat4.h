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
    Vec3 transform_vector(const Vec3& v) const;
    /// Transform a normal with *this* being the inverse-transpose (the normal matrix).
    Vec3 transform_normal(const Vec3& n) const { return transform_vector(n); }
};

/// A transform with its inverse and normal matrix (inverse transpose).
struct Transform {
    Mat4 m, inv, normal;
    Transform() = default;
    /// Throws SceneError if singular or not finite (`what` names the object).
    Transform(const Mat4& mat, const char* what);
};

}  // namespace cmlt
