#include "scene/coordinate_range.h"

#include <algorithm>
#include <cmath>

namespace cmlt {

namespace {

double abs_or_inf(double v) { return std::isnan(v) ? INFINITY : std::fabs(v); }

}  // namespace

double max_abs(const Vec3& lo, const Vec3& hi) {
    double r = 0.0;
    for (int i = 0; i < 3; ++i) r = std::max({r, abs_or_inf(lo[i]), abs_or_inf(hi[i])});
    return r;
}

double affine_reach(const Mat4& m, double extent) {
    double r = 0.0;
    for (int row = 0; row < 3; ++row) {
        double s = abs_or_inf(m.m[row][3]);
        for (int c = 0; c < 3; ++c) s += abs_or_inf(m.m[row][c]) * extent;
        r = std::max(r, s);
    }
    return r;
}

}  // namespace cmlt
