#include "math/mat4.h"

#include "util/error.h"

#include <cmath>

namespace cmlt {

Mat4 Mat4::from_row_major(const double* a) {
    Mat4 r;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) r.m[i][j] = a[i * 4 + j];
    return r;
}

Mat4 Mat4::translate(double x, double y, double z) {
    Mat4 r;
    r.m[0][3] = x;
    r.m[1][3] = y;
    r.m[2][3] = z;
    return r;
}

Mat4 Mat4::scale(double x, double y, double z) {
    Mat4 r;
    r.m[0][0] = x;
    r.m[1][1] = y;
    r.m[2][2] = z;
    return r;
}

Mat4 Mat4::rotate(double deg, double ax, double ay, double az) {
    double l = std::sqrt(ax * ax + ay * ay + az * az);
    ax /= l; ay /= l; az /= l;
    double th = deg * 3.14159265358979323846 / 180.0;
    double c = std::cos(th), s = std::sin(th), t = 1 - c;
    Mat4 r;
    r.m[0][0] = t * ax * ax + c;      r.m[0][1] = t * ax * ay - s * az; r.m[0][2] = t * ax * az + s * ay;
    r.m[1][0] = t * ax * ay + s * az; r.m[1][1] = t * ay * ay + c;      r.m[1][2] = t * ay * az - s * ax;
    r.m[2][0] = t * ax * az - s * ay; r.m[2][1] = t * ay * az + s * ax; r.m[2][2] = t * az * az + c;
    return r;
}

Mat4 Mat4::operator*(const Mat4& b) const {
    Mat4 r;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            double s = 0;
            for (int k = 0; k < 4; ++k) s += m[i][k] * b.m[k][j];
            r.m[i][j] = s;
        }
    return r;
}

Mat4 Mat4::transpose() const {
    Mat4 r;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) r.m[i][j] = m[j][i];
    return r;
}

double Mat4::determinant() const {
    const double* a = &m[0][0];
    double s0 = a[0] * a[5] - a[4] * a[1], s1 = a[0] * a[6] - a[4] * a[2];
    double s2 = a[0] * a[7] - a[4] * a[3], s3 = a[1] * a[6] - a[5] * a[2];
    double s4 = a[1] * a[7] - a[5] * a[3], s5 = a[2] * a[7] - a[6] * a[3];
    double c5 = a[10] * a[15] - a[14] * a[11], c4 = a[9] * a[15] - a[13] * a[11];
    double c3 = a[9] * a[14] - a[13] * a[10], c2 = a[8] * a[15] - a[12] * a[11];
    double c1 = a[8] * a[14] - a[12] * a[10], c0 = a[8] * a[13] - a[12] * a[9];
    return s0 * c5 - s1 * c4 + s2 * c3 + s3 * c2 - s4 * c1 + s5 * c0;
}

Mat4 Mat4::inverse(bool* ok) const {
    // Laplace expansion by 2x2 sub-determinants (as in pbrt / MESA gluInvertMatrix).
    const double* a = &m[0][0];
    double s0 = a[0] * a[5] - a[4] * a[1], s1 = a[0] * a[6] - a[4] * a[2];
    double s2 = a[0] * a[7] - a[4] * a[3], s3 = a[1] * a[6] - a[5] * a[2];
    double s4 = a[1] * a[7] - a[5] * a[3], s5 = a[2] * a[7] - a[6] * a[3];
    double c5 = a[10] * a[15] - a[14] * a[11], c4 = a[9] * a[15] - a[13] * a[11];
    double c3 = a[9] * a[14] - a[13] * a[10], c2 = a[8] * a[15] - a[12] * a[11];
    double c1 = a[8] * a[14] - a[12] * a[10], c0 = a[8] * a[13] - a[12] * a[9];
    double det = s0 * c5 - s1 * c4 + s2 * c3 + s3 * c2 - s4 * c1 + s5 * c0;
    if (!(std::fabs(det) > 0) || !std::isfinite(det)) {
        if (ok) *ok = false;
        return Mat4();
    }
    double id = 1.0 / det;
    double b[16];
    b[0] = (a[5] * c5 - a[6] * c4 + a[7] * c3) * id;
    b[1] = (-a[1] * c5 + a[2] * c4 - a[3] * c3) * id;
    b[2] = (a[13] * s5 - a[14] * s4 + a[15] * s3) * id;
    b[3] = (-a[9] * s5 + a[10] * s4 - a[11] * s3) * id;
    b[4] = (-a[4] * c5 + a[6] * c2 - a[7] * c1) * id;
    b[5] = (a[0] * c5 - a[2] * c2 + a[3] * c1) * id;
    b[6] = (-a[12] * s5 + a[14] * s2 - a[15] * s1) * id;
    b[7] = (a[8] * s5 - a[10] * s2 + a[11] * s1) * id;
    b[8] = (a[4] * c4 - a[5] * c2 + a[7] * c0) * id;
    b[9] = (-a[0] * c4 + a[1] * c2 - a[3] * c0) * id;
    b[10] = (a[12] * s4 - a[13] * s2 + a[15] * s0) * id;
    b[11] = (-a[8] * s4 + a[9] * s2 - a[11] * s0) * id;
    b[12] = (-a[4] * c3 + a[5] * c1 - a[6] * c0) * id;
    b[13] = (a[0] * c3 - a[1] * c1 + a[2] * c0) * id;
    b[14] = (-a[12] * s3 + a[13] * s1 - a[14] * s0) * id;
    b[15] = (a[8] * s3 - a[9] * s1 + a[10] * s0) * id;
    if (ok) *ok = true;
    return from_row_major(b);
}

bool Mat4::is_finite() const {
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j)
            if (!std::isfinite(m[i][j])) return false;
    return true;
}

bool Mat4::is_affine() const {
    return m[3][0] == 0 && m[3][1] == 0 && m[3][2] == 0 && m[3][3] == 1;
}

Transform::Transform(const Mat4& mat, const char* what) : m(mat) {
    if (!mat.is_finite()) CMLT_THROW(SceneError, what << ": transform has NaN or Inf entries");
    if (!mat.is_affine())
        CMLT_THROW(SceneError, what << ": transform is not affine (bottom row must be 0 0 0 1; "
                                       "matrices use the column-vector convention)");
    bool ok = false;
    inv = mat.inverse(&ok);
    if (!ok) CMLT_THROW(SceneError, what << ": transform is singular");
    normal = inv.transpose();
}

}  // namespace cmlt
