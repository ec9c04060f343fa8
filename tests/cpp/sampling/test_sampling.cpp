// Sampling routines: chi-square goodness of fit against their pdfs, pdf normalisation,
// and the discrete distribution.
//
// Significance: the family of chi-square tests in this file (and the sphere-cap test in
// test_lights.cpp) is held to a total false-alarm rate of alpha = 1e-3, Bonferroni-
// corrected over k_num_chi2_tests. Samples are deterministic (Philox), so a pass or
// fail is reproducible.
#include "chi2.h"
#include "test_util.h"

#include "math/frame.h"
#include "sampling/discrete_distribution.h"
#include "sampling/mis.h"
#include "sampling/piecewise_constant_2d.h"
#include "sampling/warp.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <utility>
#include <vector>

using namespace cmlt;
using namespace cmlt::test;

namespace {

constexpr int k_num_chi2_tests = 8;
constexpr double k_alpha = 1e-3 / k_num_chi2_tests;
constexpr uint32_t k_samples = 400000;

/// Histogram of directions on the sphere over (cos theta, phi) cells with given
/// cos-theta edges; expected counts integrate pdf numerically (sub-cell midpoints;
/// d omega = d(cos theta) d phi).
struct SphereHistogram {
    std::vector<double> cos_edges;
    int phi_bins;
    std::vector<double> obs, exp;

    SphereHistogram(std::vector<double> edges, int phi) : cos_edges(std::move(edges)), phi_bins(phi) {
        obs.assign((cos_edges.size() - 1) * phi_bins, 0);
        exp.assign(obs.size(), 0);
    }
    int cell(const Vec3& w) const {
        double c = std::clamp(double(w.z), -1.0, 1.0);
        auto it = std::upper_bound(cos_edges.begin(), cos_edges.end(), c);
        int ci = std::clamp(int(it - cos_edges.begin()) - 1, 0, int(cos_edges.size()) - 2);
        double phi = std::atan2(double(w.y), double(w.x));
        if (phi < 0) phi += 2 * M_PI;
        int pi = std::min(phi_bins - 1, int(phi / (2 * M_PI) * phi_bins));
        return ci * phi_bins + pi;
    }
    void add(const Vec3& w) { obs[cell(w)] += 1; }
    void integrate(const std::function<double(const Vec3&)>& pdf, double n, int sub = 12) {
        for (size_t ci = 0; ci + 1 < cos_edges.size(); ++ci)
            for (int pi = 0; pi < phi_bins; ++pi) {
                double c0 = cos_edges[ci], c1 = cos_edges[ci + 1];
                double p0 = 2 * M_PI * pi / phi_bins, p1 = 2 * M_PI * (pi + 1) / phi_bins;
                double sum = 0;
                for (int a = 0; a < sub; ++a)
                    for (int b = 0; b < sub; ++b) {
                        double c = c0 + (a + 0.5) / sub * (c1 - c0);
                        double ph = p0 + (b + 0.5) / sub * (p1 - p0);
                        double s = std::sqrt(std::max(0.0, 1 - c * c));
                        sum += pdf(Vec3(float(s * std::cos(ph)), float(s * std::sin(ph)), float(c)));
                    }
                exp[ci * phi_bins + pi] = n * sum / (sub * sub) * (c1 - c0) * (p1 - p0);
            }
    }
};

std::vector<double> uniform_edges(double a, double b, int n) {
    std::vector<double> e;
    for (int i = 0; i <= n; ++i) e.push_back(a + (b - a) * i / n);
    return e;
}

void expect_chi2(const std::vector<double>& obs, const std::vector<double>& exp, int cols) {
    Chi2Result r = chi2_test(obs, exp);
    EXPECT_TRUE(r.passed(k_alpha)) << r.message << "\n" << dump_table(obs, exp, cols);
}

}  // namespace

TEST(Chi2Helper, RejectsAWrongDistributionAndAcceptsTheRightOne) {
    // The helper itself must be able to fail: uniform samples against a linear pdf.
    std::vector<double> obs(20, 0), exp_uniform(20), exp_linear(20);
    for (uint32_t i = 0; i < 100000; ++i) obs[std::min(19, int(uniform2(1, i).x * 20))] += 1;
    for (int b = 0; b < 20; ++b) {
        exp_uniform[b] = 100000.0 / 20;
        double x0 = b / 20.0, x1 = (b + 1) / 20.0;
        exp_linear[b] = 100000.0 * (x1 * x1 - x0 * x0);
    }
    EXPECT_TRUE(chi2_test(obs, exp_uniform).passed(k_alpha));
    EXPECT_FALSE(chi2_test(obs, exp_linear).passed(k_alpha));
    EXPECT_NEAR(chi2_sf(3.84145882, 1), 0.05, 1e-6);
    EXPECT_NEAR(chi2_sf(18.3070381, 10), 0.05, 1e-6);
}

TEST(Sampling, CosineHemisphereChi2) {
    SphereHistogram h(uniform_edges(-1, 1, 20), 16);
    for (uint32_t i = 0; i < k_samples; ++i) h.add(square_to_cosine_hemisphere(uniform2(2, i)));
    h.integrate([](const Vec3& w) { return square_to_cosine_hemisphere_pdf(w); }, k_samples);
    expect_chi2(h.obs, h.exp, 16);
}

TEST(Sampling, UniformSphereChi2) {
    SphereHistogram h(uniform_edges(-1, 1, 20), 16);
    for (uint32_t i = 0; i < k_samples; ++i) h.add(square_to_uniform_sphere(uniform2(3, i)));
    h.integrate([](const Vec3& w) { return square_to_uniform_sphere_pdf(w); }, k_samples);
    expect_chi2(h.obs, h.exp, 16);
}

TEST(Sampling, UniformConeChi2) {
    const float cos_max = 0.7f, omc = 1.f - cos_max;
    std::vector<double> edges = uniform_edges(-1, cos_max, 4);
    for (int i = 1; i <= 16; ++i) edges.push_back(cos_max + (1.0 - cos_max) * i / 16);
    SphereHistogram h(edges, 16);
    for (uint32_t i = 0; i < k_samples; ++i) h.add(square_to_uniform_cone(uniform2(4, i), omc));
    h.integrate([&](const Vec3& w) { return w.z >= cos_max ? 1.0 / (2 * M_PI * omc) : 0.0; }, k_samples);
    expect_chi2(h.obs, h.exp, 16);
}

TEST(Sampling, UniformDiskConcentricChi2) {
    // Cells of equal area: r^2 in 10 bins x 16 angle bins; all samples inside the disk.
    const int nr = 10, nt = 16;
    std::vector<double> obs(nr * nt, 0), exp(nr * nt, double(k_samples) / (nr * nt));
    for (uint32_t i = 0; i < k_samples; ++i) {
        Vec2 p = square_to_uniform_disk_concentric(uniform2(5, i));
        double r2 = double(p.x) * p.x + double(p.y) * p.y;
        ASSERT_LE(r2, 1.0 + 1e-6);
        double th = std::atan2(double(p.y), double(p.x));
        if (th < 0) th += 2 * M_PI;
        int a = std::min(nr - 1, int(r2 * nr)), b = std::min(nt - 1, int(th / (2 * M_PI) * nt));
        obs[a * nt + b] += 1;
    }
    expect_chi2(obs, exp, nt);
}

TEST(Sampling, UniformTriangleChi2) {
    // The triangle split into n^2 congruent sub-triangles of equal area.
    const int n = 12;
    std::vector<double> obs(2 * n * n, 0), exp(2 * n * n, 0);
    auto index = [&](int i, int j, bool up) { return (i * n + j) * 2 + (up ? 0 : 1); };
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            if (i + j <= n - 1) exp[index(i, j, true)] = double(k_samples) / (n * n);
            if (i + j <= n - 2) exp[index(i, j, false)] = double(k_samples) / (n * n);
        }
    for (uint32_t k = 0; k < k_samples; ++k) {
        Vec2 b = square_to_uniform_triangle(uniform2(6, k));
        ASSERT_GE(b.x, 0.f);
        ASSERT_GE(b.y, 0.f);
        ASSERT_LE(b.x + b.y, 1.f + 1e-6f);
        double x = b.x * n, y = b.y * n;
        int i = std::min(n - 1, int(x)), j = std::min(n - 1, int(y));
        bool up = (x - i) + (y - j) < 1.0;
        if (i + j > n - 1) { up = false; }
        if (!up && i + j > n - 2) up = true;  // rounding at the hypotenuse
        obs[index(i, j, up)] += 1;
    }
    expect_chi2(obs, exp, 2 * n);
}

TEST(Sampling, PdfsIntegrateToOne) {
    // Midpoint rule over the sphere in (cos theta, phi).
    auto integrate = [](const std::function<double(const Vec3&)>& pdf, int nc = 400, int np = 200) {
        double sum = 0;
        for (int a = 0; a < nc; ++a)
            for (int b = 0; b < np; ++b) {
                double c = -1 + (a + 0.5) * 2.0 / nc, ph = (b + 0.5) * 2 * M_PI / np;
                double s = std::sqrt(1 - c * c);
                sum += pdf(Vec3(float(s * std::cos(ph)), float(s * std::sin(ph)), float(c)));
            }
        return sum * (2.0 / nc) * (2 * M_PI / np);
    };
    EXPECT_NEAR(integrate([](const Vec3& w) { return square_to_cosine_hemisphere_pdf(w); }), 1.0, 1e-3);
    EXPECT_NEAR(integrate([](const Vec3& w) { return square_to_uniform_sphere_pdf(w); }), 1.0, 1e-5);
    EXPECT_NEAR(integrate([](const Vec3& w) { return square_to_uniform_hemisphere_pdf(w); }), 1.0, 1e-3);
    EXPECT_NEAR(integrate([](const Vec3& w) { return square_to_uniform_cone_pdf(w, 0.3f); }), 1.0, 5e-3);
}

TEST(Sampling, ConePdfMatchesSamplesForTinyCones) {
    // The sun: 0.53 degrees; 1 - cos is ~1e-5, where float cancellation would bite.
    double half = 0.5 * 0.53 * M_PI / 180;
    float omc = float(2 * std::sin(half / 2) * std::sin(half / 2));
    for (uint32_t i = 0; i < 1000; ++i) {
        Vec3 w = square_to_uniform_cone(uniform2(7, i), omc);
        ASSERT_NEAR(length(w), 1.0f, 1e-5f);
        ASSERT_GT(square_to_uniform_cone_pdf(normalize(w), omc), 0.f) << i;
    }
    EXPECT_EQ(square_to_uniform_cone_pdf(Vec3(0.1f, 0.f, 0.995f), omc), 0.f);
}

TEST(Sampling, DiscreteDistributionChi2AndPmf) {
    std::vector<double> w = {1, 0, 3, 6, 0.5};
    DiscreteDistribution d(w);
    double total = 10.5;
    for (size_t i = 0; i < w.size(); ++i) EXPECT_NEAR(d.pmf(i), w[i] / total, 1e-7);
    std::vector<double> obs(w.size(), 0), exp(w.size());
    for (size_t i = 0; i < w.size(); ++i) exp[i] = k_samples * w[i] / total;
    for (uint32_t k = 0; k < k_samples; ++k) {
        float pmf, ur;
        size_t i = d.sample(uniform2(8, k).x, &pmf, &ur);
        ASSERT_NE(i, 1u) << "zero-weight bin sampled";
        ASSERT_EQ(pmf, d.pmf(i));
        ASSERT_GE(ur, 0.f);
        ASSERT_LT(ur, 1.f);
        obs[i] += 1;
    }
    expect_chi2(obs, exp, 5);
    // All-zero weights: uniform.
    DiscreteDistribution z({0, 0});
    EXPECT_FLOAT_EQ(z.pmf(0), 0.5f);
}

TEST(Sampling, PowerHeuristic) {
    EXPECT_FLOAT_EQ(power_heuristic(1.f, 1.f), 0.5f);
    EXPECT_FLOAT_EQ(power_heuristic(3.f, 1.f), 0.9f);
    EXPECT_EQ(power_heuristic(0.f, 0.f), 0.f);
    EXPECT_EQ(power_heuristic(k_infinity, 2.f), 1.f);
    EXPECT_NEAR(power_heuristic(2.f, 5.f) + power_heuristic(5.f, 2.f), 1.f, 1e-6f);
}

TEST(Rng, PhiloxKnownAnswers) {
    // Random123 known-answer vectors for philox4x32_10.
    auto z = philox4x32({0, 0, 0, 0}, {0, 0});
    EXPECT_EQ(z, (Philox4x32Counter{0x6627e8d5u, 0xe169c58du, 0xbc57ac4cu, 0x9b00dbd8u}));
    auto f = philox4x32({~0u, ~0u, ~0u, ~0u}, {~0u, ~0u});
    EXPECT_EQ(f, (Philox4x32Counter{0x408f276du, 0x41c83b0eu, 0xa20bc7c6u, 0x6d5451fdu}));
    auto p = philox4x32({0x243f6a88u, 0x85a308d3u, 0x13198a2eu, 0x03707344u}, {0xa4093822u, 0x299f31d0u});
    EXPECT_EQ(p, (Philox4x32Counter{0xd16cfe09u, 0x94fdccebu, 0x5001e420u, 0x24126ea1u}));
}

TEST(Rng, StreamsAreKeyedNotSequential) {
    PixelSampler a(7, 10, 3), b(7, 10, 3), c(8, 10, 3), d(7, 11, 3);
    a.set_dimension(5);
    for (int i = 0; i < 5; ++i) b.get1d();
    EXPECT_EQ(a.get1d(), b.get1d());  // dimension 5 either way
    a.set_dimension(0);
    c.set_dimension(0);
    d.set_dimension(0);
    float va = a.get1d();
    EXPECT_NE(va, c.get1d());
    EXPECT_NE(va, d.get1d());
    for (int i = 0; i < 1000; ++i) {
        float u = a.get1d();
        ASSERT_GE(u, 0.f);
        ASSERT_LT(u, 1.f);
    }
}

// ---- PiecewiseConstant2D: the inverse CDF --------------------------------------------------

namespace {

/// The distribution's CDFs as PiecewiseConstant2D builds them, inverted by std::upper_bound
/// over the whole CDF (no guide table): the sample it must return, bit for bit.
struct ReferenceInverse {
    int nx, ny;
    std::vector<float> w;
    std::vector<double> marginal, cond;
    ReferenceInverse(const std::vector<float>& weights, int nx_, int ny_) : nx(nx_), ny(ny_) {
        double total = 0.0;
        for (float v : weights) total += double(v);
        const double scale = double(nx * ny) / total;
        for (float v : weights) w.push_back(float(double(v) * scale));
        marginal.assign(size_t(ny) + 1, 0.0);
        cond.assign(size_t(ny) * size_t(nx + 1), 0.0);
        for (int y = 0; y < ny; ++y) {
            double* c = &cond[size_t(y) * size_t(nx + 1)];
            double row = 0.0;
            for (int x = 0; x < nx; ++x) c[x + 1] = row += double(w[size_t(y) * nx + x]);
            for (int x = 1; x <= nx; ++x) c[x] = row > 0.0 ? c[x] / row : double(x) / nx;
            c[nx] = 1.0;
            marginal[size_t(y) + 1] = marginal[size_t(y)] + row;
        }
        for (int y = 1; y <= ny; ++y) marginal[size_t(y)] /= marginal[size_t(ny)];
        marginal[size_t(ny)] = 1.0;
    }
    static int invert(const double* cdf, int n, double u, double* frac) {
        int i = int(std::upper_bound(cdf, cdf + n + 1, u) - cdf) - 1;
        i = std::clamp(i, 0, n - 1);
        while (i > 0 && !(cdf[i + 1] > cdf[i])) --i;
        while (i < n - 1 && !(cdf[i + 1] > cdf[i])) ++i;
        const double width = cdf[i + 1] - cdf[i];
        *frac = std::clamp(width > 0.0 ? (u - cdf[i]) / width : 0.5, 0.0, std::nextafter(1.0, 0.0));
        return i;
    }
    Vec2 sample(const Vec2& u, float* pdf) const {
        double fy, fx;
        const int y = invert(marginal.data(), ny, double(u.y), &fy);
        const int x = invert(&cond[size_t(y) * size_t(nx + 1)], nx, double(u.x), &fx);
        *pdf = w[size_t(y) * nx + x];
        float px = float((double(x) + fx) / nx), py = float((double(y) + fy) / ny);
        px = std::min(px, std::nextafter(float(x + 1) / float(nx), 0.f));
        py = std::min(py, std::nextafter(float(y + 1) / float(ny), 0.f));
        return Vec2(px, py);
    }
};

}  // namespace

TEST(PiecewiseConstant2D, GuidedInverseIsTheWholeCdfSearchBitForBit) {
    uint32_t state = 7u;
    auto next = [&] {
        state = state * 1664525u + 1013904223u;
        return float(state >> 8) / float(1u << 24);
    };
    auto check = [&](const std::vector<float>& weights, int nx, int ny) {
        const PiecewiseConstant2D dist(weights, nx, ny);
        const ReferenceInverse ref(weights, nx, ny);
        std::vector<Vec2> us;
        for (int i = 0; i < 20000; ++i) us.push_back(Vec2(next(), next()));
        // on the CDFs' own values (bin edges, the repeated edges of empty bins) and on
        // the guide's bucket edges k / 32
        for (double m : ref.marginal)
            for (double c : ref.cond) us.push_back(Vec2(float(c), float(m)));
        for (int k = 0; k <= PiecewiseConstant2D::k_guide; ++k)
            us.push_back(Vec2(float(k) / PiecewiseConstant2D::k_guide, next()));
        us.push_back(Vec2(std::nextafter(1.f, 0.f), std::nextafter(1.f, 0.f)));
        for (const Vec2& u : us) {
            float pdf = 0.f, pdf_ref = 0.f;
            const Vec2 got = dist.sample(u, &pdf), want = ref.sample(u, &pdf_ref);
            ASSERT_EQ(got.x, want.x) << nx << "x" << ny << ", u = (" << u.x << ", " << u.y << ")";
            ASSERT_EQ(got.y, want.y) << nx << "x" << ny << ", u = (" << u.x << ", " << u.y << ")";
            ASSERT_EQ(pdf, pdf_ref) << nx << "x" << ny << ", u = (" << u.x << ", " << u.y << ")";
        }
    };
    // 4 x 2 cells whose CDF values are floats exactly (the total is the cell count, the
    // rows sum to powers of two): u lands on every edge, empty cells included.
    check({1.f, 0.f, 1.f, 2.f, 0.f, 4.f, 0.f, 0.f}, 4, 2);
    // 13 x 7 cells (fewer than the guide's buckets), empty cells and an empty row; and
    // 300 x 40 (several entries per bucket) with runs of empty cells.
    for (auto [nx, ny] : {std::pair<int, int>{13, 7}, std::pair<int, int>{300, 40}}) {
        std::vector<float> weights(size_t(nx * ny));
        for (int i = 0; i < nx * ny; ++i)
            weights[size_t(i)] = (i % 5 == 0 || i / nx == 3 || (i % nx) / 20 == 4) ? 0.f : next() * 10.f;
        check(weights, nx, ny);
    }
}
