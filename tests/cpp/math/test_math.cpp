// Matrices (column-vector convention), frames, safe maths.
#include "math/frame.h"
#include "math/mat4.h"
#include "math/safe_math.h"
#include "math/sincos.h"
#include "util/error.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace cmlt;

TEST(Mat4, InverseAndTransforms) {
    Mat4 m = Mat4::translate(1, 2, 3) * Mat4::rotate(30, 0, 1, 1) * Mat4::scale(2, 3, 0.5);
    bool ok = false;
    Mat4 inv = m.inverse(&ok);
    ASSERT_TRUE(ok);
    Mat4 id = m * inv;
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) EXPECT_NEAR(id.m[i][j], i == j ? 1.0 : 0.0, 1e-12);
    // Column-vector convention: translation in column 3.
    Vec3 p = Mat4::translate(1, 2, 3).transform_point(Vec3(1, 1, 1));
    EXPECT_EQ(p, Vec3(2, 3, 4));
    EXPECT_EQ(Mat4::translate(1, 2, 3).transform_vector(Vec3(1, 1, 1)), Vec3(1, 1, 1));
    EXPECT_NEAR(Mat4::scale(2, 3, 4).determinant(), 24.0, 1e-12);
}

TEST(Mat4, NormalMatrixKeepsNormalsPerpendicular) {
    Transform xf(Mat4::rotate(40, 1, 0, 0) * Mat4::scale(1, 5, 0.2), "test");
    Vec3 a(1, 0, 0), b(0, 1, 1);
    Vec3 n = cross(a, b);
    Vec3 nw = xf.normal.transform_normal(n);
    EXPECT_NEAR(dot(nw, xf.m.transform_vector(a)), 0.f, 1e-5f);
    EXPECT_NEAR(dot(nw, xf.m.transform_vector(b)), 0.f, 1e-5f);
}

TEST(Mat4, SingularAndNonFiniteTransformsThrow) {
    EXPECT_THROW(Transform(Mat4::scale(1, 0, 1), "x"), SceneError);
    Mat4 nan;
    nan.m[0][3] = std::nan("");
    EXPECT_THROW(Transform(nan, "x"), SceneError);
    Mat4 proj;
    proj.m[3][2] = -1;
    EXPECT_THROW(Transform(proj, "x"), SceneError);
}

TEST(Frame, Orthonormal) {
    for (Vec3 n : {Vec3(0, 0, 1), Vec3(0, 0, -1), Vec3(1, 0, 0), normalize(Vec3(1, -2, 3)),
                   normalize(Vec3(1e-8f, 0, -1))}) {
        Frame f(n);
        EXPECT_NEAR(length(f.s), 1.f, 1e-5f);
        EXPECT_NEAR(length(f.t), 1.f, 1e-5f);
        EXPECT_NEAR(dot(f.s, f.t), 0.f, 1e-5f);
        EXPECT_NEAR(dot(f.s, f.n), 0.f, 1e-5f);
        EXPECT_NEAR(dot(cross(f.s, f.t), f.n), 1.f, 1e-5f);
        Vec3 v(0.3f, -0.2f, 0.9f);
        Vec3 r = f.to_world(f.to_local(v));
        EXPECT_NEAR(length(r - v), 0.f, 1e-5f);
    }
}

TEST(SafeMath, NoNaNJustOutsideTheDomain) {
    EXPECT_EQ(safe_sqrt(-1e-7f), 0.f);
    EXPECT_EQ(safe_acos(1.0000001f), 0.f);
    EXPECT_EQ(normalize(Vec3(0.f)), Vec3(0.f));
}

// The samplers' sine and cosine (math/sincos.h) against double precision: within a few
// float ulp everywhere on their domains, on the unit circle, with the quadrants and the
// concentric map's two halves joined up. A wrong coefficient, quadrant or swap fails by
// orders of magnitude more than the tolerance.
TEST(SinCos, MatchDoublePrecisionOnTheSamplersDomains) {
    const double two_pi = 6.283185307179586476925;
    double worst_turn = 0.0, worst_quarter = 0.0, worst_norm = 0.0;
    for (int i = 0; i <= 1 << 20; ++i) {
        const float u = float(i) / float(1 << 20);
        float s, c;
        sincos_turn(u, &s, &c);
        worst_turn = std::max({worst_turn, std::fabs(s - std::sin(two_pi * double(u))),
                               std::fabs(c - std::cos(two_pi * double(u)))});
        worst_norm = std::max(worst_norm, std::fabs(double(s) * s + double(c) * c - 1.0));
        const float f = u - 0.5f;
        sincos_quarter(f, &s, &c);
        const double x = 0.25 * two_pi * double(f);
        worst_quarter = std::max({worst_quarter, std::fabs(s - std::sin(x)), std::fabs(c - std::cos(x))});
    }
    EXPECT_LT(worst_turn, 3e-7);
    EXPECT_LT(worst_quarter, 2e-7);
    EXPECT_LT(worst_norm, 6e-7);
    // angles beyond one turn reduce exactly (the quadrant of negative u too)
    for (float u : {-0.75f, -0.3f, 1.25f, 7.6f}) {
        float s, c;
        sincos_turn(u, &s, &c);
        EXPECT_NEAR(s, std::sin(two_pi * double(u)), 3e-7) << u;
        EXPECT_NEAR(c, std::cos(two_pi * double(u)), 3e-7) << u;
    }
}

// The double-precision turn (the Box–Muller angles of the Metropolis kernels): within a
// few double ulps of libm's sin and cos of 2π u over a turn — long double's as the
// reference, so libm's own rounding does not count against it.
TEST(SinCos, DoubleTurnMatchesLibmToAFewUlps) {
    const long double two_pi = 6.283185307179586476925286766559L;
    double worst = 0.0;
    for (int i = 0; i <= 1 << 20; ++i) {
        for (double u : {double(i) / double(1 << 20), (double(i) + 0.3183098861837907) / double(1 << 20)}) {
            if (u > 1.0) continue;
            double s, c;
            sincos_turn_double(u, &s, &c);
            const long double a = two_pi * (long double)u;
            worst = std::max({worst, double(std::fabs((long double)s - std::sin(a))),
                              double(std::fabs((long double)c - std::cos(a)))});
        }
    }
    EXPECT_LT(worst, 1e-15);
    EXPECT_GT(worst, 0.0);  // not libm itself
    double s, c;
    sincos_turn_double(0.25, &s, &c);  // exact quadrants
    EXPECT_EQ(s, 1.0);
    EXPECT_EQ(c, 0.0);
    sincos_turn_double(0.5, &s, &c);
    EXPECT_EQ(c, -1.0);
}

TEST(SinCos, ConcentricDiskIsShirleyChiusMap) {
    const double quarter_pi = 0.785398163397448309616;
    double worst = 0.0;
    for (int i = 0; i <= 512; ++i)
        for (int j = 0; j <= 512; ++j) {
            const float ux = float(i) / 512.f, uy = float(j) / 512.f;
            const double x = 2.0 * ux - 1.0, y = 2.0 * uy - 1.0;
            double r = 0.0, th = 0.0;
            if (std::fabs(x) > std::fabs(y)) {
                r = x;
                th = quarter_pi * (y / x);
            } else if (y != 0.0) {
                r = y;
                th = 2.0 * quarter_pi - quarter_pi * (x / y);
            }
            const Vec2 d = concentric_disk(ux, uy);
            worst = std::max({worst, std::fabs(d.x - r * std::cos(th)), std::fabs(d.y - r * std::sin(th))});
        }
    EXPECT_LT(worst, 3e-7);
    EXPECT_EQ(concentric_disk(0.5f, 0.5f).x, 0.f);
    EXPECT_EQ(concentric_disk(0.5f, 0.5f).y, 0.f);
}
