// Subdivision surfaces (geometry/subdivision.cpp, OpenSubdiv):
//  1. Catmull-Clark of a cube converges to a rounded, sphere-like limit: the refined
//     vertices' distances from the centre lie in a narrow band (the cage's span 1..sqrt 3),
//     the area is below the cage's and above the inscribed sphere's, the normals are unit
//     and point outward;
//  2. creases and corners: a cube with all 12 edges infinitely sharp stays the cube; a
//     semi-sharp crease pulls the surface toward its edge; a sharp corner is interpolated;
//  3. holes drop their faces; face-varying data and vertex data follow the refinement
//     (a bilinear quad reproduces linear uvs exactly); bad topology names the mesh.
#include "geometry/subdivision.h"
#include "util/error.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace cmlt;

namespace {

SubdivInput cube(int level) {
    SubdivInput in;
    for (int i = 0; i < 8; ++i) {
        in.points.push_back(i & 1 ? 1.0 : -1.0);
        in.points.push_back(i & 2 ? 1.0 : -1.0);
        in.points.push_back(i & 4 ? 1.0 : -1.0);
    }
    // outward-facing quads (counter-clockwise seen from outside)
    in.face_indices = {0, 2, 3, 1,  4, 5, 7, 6,  0, 1, 5, 4,  2, 6, 7, 3,  0, 4, 6, 2,  1, 3, 7, 5};
    in.face_counts.assign(6, 4);
    in.level = level;
    in.name = "/cube";
    return in;
}

double norm(const double* p) { return std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]); }

double area(const SubdivResult& r) {
    double a = 0;
    size_t c = 0;
    for (int32_t n : r.face_counts) {
        const double* p0 = &r.points[3 * size_t(r.face_indices[c])];
        for (int k = 1; k + 1 < n; ++k) {
            const double* p1 = &r.points[3 * size_t(r.face_indices[c + size_t(k)])];
            const double* p2 = &r.points[3 * size_t(r.face_indices[c + size_t(k) + 1])];
            double u[3], v[3], x[3];
            for (int i = 0; i < 3; ++i) u[i] = p1[i] - p0[i], v[i] = p2[i] - p0[i];
            x[0] = u[1] * v[2] - u[2] * v[1];
            x[1] = u[2] * v[0] - u[0] * v[2];
            x[2] = u[0] * v[1] - u[1] * v[0];
            a += 0.5 * norm(x);
        }
        c += size_t(n);
    }
    return a;
}

}  // namespace

TEST(Subdivision, CubeConvergesToARoundLimit) {
    SubdivResult r = subdivide(cube(4));
    const size_t n = r.points.size() / 3;
    ASSERT_EQ(r.face_counts.size(), 6u * 256u);  // 4^4 quads per face
    double lo = 1e9, hi = 0;
    for (size_t v = 0; v < n; ++v) {
        const double* p = &r.points[3 * v];
        const double* q = &r.normals[3 * v];
        double d = norm(p);
        lo = std::min(lo, d);
        hi = std::max(hi, d);
        ASSERT_TRUE(std::isfinite(q[0]) && std::isfinite(q[1]) && std::isfinite(q[2]));
        EXPECT_NEAR(norm(q), 1.0, 1e-9) << v;
        EXPECT_GT(p[0] * q[0] + p[1] * q[1] + p[2] * q[2], 0.5 * d) << "normal points inward at " << v;
    }
    // the cage spans distances 1 (face centres) .. 1.732 (corners); the limit is round
    EXPECT_GT(lo, 0.55);
    EXPECT_LT(hi / lo, 1.2) << lo << " .. " << hi;
    double a = area(r);
    EXPECT_LT(a, 24.0);                          // the cage's area
    EXPECT_GT(a, 4.0 * M_PI * lo * lo);          // a sphere inside the surface
    for (int32_t f : r.face_parent) EXPECT_TRUE(f >= 0 && f < 6);
    // refinement converges: the polygon areas grow toward the limit's by ever smaller steps
    double a2 = area(subdivide(cube(2))), a3 = area(subdivide(cube(3)));
    EXPECT_LT(a2, a3);
    EXPECT_LT(a3, a);
    EXPECT_LT(a - a3, 0.5 * (a3 - a2));
    EXPECT_LT(a - a3, 0.01 * a);
}

TEST(Subdivision, SharpEdgesKeepTheCube) {
    SubdivInput in = cube(3);
    // every edge of the cube as a 2-vertex crease chain, infinitely sharp
    const int edges[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3},
                              {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
    for (auto& e : edges) {
        in.crease_indices.push_back(e[0]);
        in.crease_indices.push_back(e[1]);
        in.crease_lengths.push_back(2);
    }
    in.crease_sharpnesses.assign(12, 10.f);
    SubdivResult r = subdivide(in);
    for (size_t v = 0; v < r.points.size() / 3; ++v) {
        const double* p = &r.points[3 * v];
        double m = std::max(std::fabs(p[0]), std::max(std::fabs(p[1]), std::fabs(p[2])));
        EXPECT_NEAR(m, 1.0, 1e-6) << "vertex " << v << " left the cube's faces";
    }
    EXPECT_NEAR(area(r), 24.0, 1e-5);  // OpenSubdiv's weights are floats
}

TEST(Subdivision, SemiSharpCreasePullsTowardItsEdge) {
    // the surface point closest to the midpoint of edge (3, 7) (x = y = 1) is further out
    // the sharper that edge's crease
    double prev = 0;
    for (float sharp : {0.f, 1.f, 3.f, 10.f}) {
        SubdivInput in = cube(4);
        in.crease_indices = {3, 7};
        in.crease_lengths = {2};
        in.crease_sharpnesses = {sharp};
        SubdivResult r = subdivide(in);
        double best = 0;
        for (size_t v = 0; v < r.points.size() / 3; ++v) {
            const double* p = &r.points[3 * v];
            best = std::max(best, (p[0] + p[1]) / std::sqrt(2.0));
        }
        EXPECT_GT(best, prev + 1e-3) << "sharpness " << sharp;
        EXPECT_LT(best, std::sqrt(2.0));  // (its ends are darts: smooth, below the cage edge)
        prev = best;
    }
}

TEST(Subdivision, SharpCornerIsInterpolated) {
    SubdivInput in = cube(3);
    in.corner_indices = {7};  // (1, 1, 1)
    in.corner_sharpnesses = {10.f};
    SubdivResult r = subdivide(in);
    double best = 1e9;
    for (size_t v = 0; v < r.points.size() / 3; ++v) {
        const double* p = &r.points[3 * v];
        double d[3] = {p[0] - 1, p[1] - 1, p[2] - 1};
        best = std::min(best, norm(d));
    }
    EXPECT_LT(best, 1e-9);
    // without it the limit stays well inside the corner
    SubdivResult smooth = subdivide(cube(3));
    double far = 0;
    for (size_t v = 0; v < smooth.points.size() / 3; ++v) far = std::max(far, norm(&smooth.points[3 * v]));
    EXPECT_LT(far, 1.2);
}

TEST(Subdivision, HolesFaceVaryingAndVertexData) {
    SubdivInput in = cube(2);
    in.hole_indices = {1};
    SubdivResult r = subdivide(in);
    EXPECT_EQ(r.face_counts.size(), 5u * 16u);
    for (int32_t f : r.face_parent) EXPECT_NE(f, 1);

    // bilinear quad with linear uvs and a linear vertex datum: reproduced exactly
    SubdivInput q;
    q.name = "/quad";
    q.points = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0};
    q.face_counts = {4};
    q.face_indices = {0, 1, 2, 3};
    q.scheme = SubdivScheme::bilinear;
    q.level = 3;
    SubdivFVarChannel uv;
    uv.width = 2;
    uv.values = {0, 0, 1, 0, 1, 1, 0, 1};
    uv.indices = {0, 1, 2, 3};
    q.face_varying.push_back(uv);
    q.vertex_width = 1;
    q.vertex_data = {0.0, 2.0, 2.0, 0.0};  // = x + 1
    SubdivResult b = subdivide(q);
    ASSERT_EQ(b.face_varying.size(), 1u);
    const SubdivFVarChannel& out = b.face_varying[0];
    size_t c = 0;
    for (size_t f = 0; f < b.face_counts.size(); ++f)
        for (int k = 0; k < b.face_counts[f]; ++k, ++c) {
            const double* p = &b.points[3 * size_t(b.face_indices[c])];
            const double* t = &out.values[2 * size_t(out.indices[c])];
            EXPECT_NEAR(t[0], (p[0] + 1) / 2, 1e-9);
            EXPECT_NEAR(t[1], (p[1] + 1) / 2, 1e-9);
            EXPECT_NEAR(p[2], 0.0, 1e-12);
            EXPECT_NEAR(b.vertex_data[size_t(b.face_indices[c])], p[0] + 1, 1e-9);
        }
}

TEST(Subdivision, BadTopologyNamesTheMesh) {
    SubdivInput in = cube(2);
    in.face_indices[5] = 42;
    try {
        subdivide(in);
        FAIL() << "accepted an out-of-range index";
    } catch (const SceneError& e) {
        EXPECT_NE(std::string(e.what()).find("/cube"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("42"), std::string::npos) << e.what();
    }
    SubdivInput lv = cube(0);
    EXPECT_THROW(subdivide(lv), SceneError);
}
