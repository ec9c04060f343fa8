// Pixel filters: each integrates to 1, its sampler follows its pdf (chi-square), the
// weights f/pdf make the sampled estimate unbiased, and the splat footprint is the
// filter at the pixel centres.
//
// The chi-square tests bin 200,000 offsets (deterministic: Philox via uniform2) into
// 16 x 16 cells over the support; the expected counts come from the sampler's own
// tabulated pdf, which the test separately checks to be |f| / ∫|f| to within the
// table's resolution. Significance: alpha = 1e-3 over the five filters (Bonferroni).
#include "chi2.h"
#include "test_util.h"

#include "film/filter.h"
#include "util/error.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

using namespace cmlt;

namespace {

constexpr FilterKind k_kinds[] = {FilterKind::box, FilterKind::triangle, FilterKind::gaussian, FilterKind::mitchell,
                                  FilterKind::blackman_harris};
constexpr double k_alpha = 1e-3 / 5;

class FilterTest : public ::testing::TestWithParam<FilterKind> {
protected:
    PixelFilter filter() const { return PixelFilter(GetParam(), PixelFilter::default_radius(GetParam())); }
};

std::string kind_name(const ::testing::TestParamInfo<FilterKind>& info) {
    std::string s = PixelFilter::name_of(info.param);
    for (char& c : s)
        if (c == '-') c = '_';
    return s;
}

}  // namespace

TEST_P(FilterTest, IntegratesToOne) {
    const PixelFilter f = filter();
    const double r = f.radius();
    // midpoint rule on a 600 x 600 grid (a different rule from the constructor's Simpson)
    const int n = 600;
    const double h = 2 * r / n;
    double s = 0.0;
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) s += f.evaluate(-r + (i + 0.5) * h, -r + (j + 0.5) * h);
    EXPECT_NEAR(s * h * h, 1.0, 2e-4);
    EXPECT_NEAR(f.integral_1d(r), 1.0, 1e-9);
    EXPECT_NEAR(f.integral_1d(0.0), 0.5, 1e-9);  // symmetric
    EXPECT_EQ(f.evaluate_1d(r + 1e-3), 0.0);
    EXPECT_NEAR(f.evaluate_1d(r), 0.0, GetParam() == FilterKind::box ? 1.0 : 1e-3);
}

TEST_P(FilterTest, SamplingMatchesItsPdf) {
    const PixelFilter f = filter();
    const double r = f.radius();
    const int cells = 16, n = 200000;
    std::vector<double> obs(size_t(cells * cells), 0.0), expd(size_t(cells * cells), 0.0);
    for (int i = 0; i < n; ++i) {
        const PixelFilter::Sample s = f.sample(test::uniform2(20, uint32_t(i)));
        ASSERT_LE(std::fabs(s.offset.x), r);
        ASSERT_LE(std::fabs(s.offset.y), r);
        const int cx = std::min(cells - 1, int((s.offset.x + r) / (2 * r) * cells));
        const int cy = std::min(cells - 1, int((s.offset.y + r) / (2 * r) * cells));
        obs[size_t(cy * cells + cx)] += 1;
    }
    // the cells' probabilities from pdf_1d, integrated over 64 sub-bins per cell
    std::vector<double> p1(size_t(cells), 0.0);
    const int sub = 64;
    const double h = 2 * r / (cells * sub);
    for (int c = 0; c < cells; ++c)
        for (int k = 0; k < sub; ++k) p1[size_t(c)] += f.pdf_1d(-r + (c * sub + k + 0.5) * h) * h;
    for (int cy = 0; cy < cells; ++cy)
        for (int cx = 0; cx < cells; ++cx) expd[size_t(cy * cells + cx)] = n * p1[size_t(cx)] * p1[size_t(cy)];
    const test::Chi2Result res = test::chi2_test(obs, expd);
    EXPECT_TRUE(res.passed(k_alpha)) << res.message << "\n" << test::dump_table(obs, expd, cells);

    // the tabulated pdf is |f1| / ∫|f1| to within the table's resolution
    double abs_int = 0.0;
    const int m = 4000;
    for (int i = 0; i < m; ++i) abs_int += std::fabs(f.evaluate_1d(-r + (i + 0.5) * 2 * r / m)) * 2 * r / m;
    for (int i = 0; i < 50; ++i) {
        const double x = -r + (i + 0.5) * 2 * r / 50;
        EXPECT_NEAR(f.pdf_1d(x), std::fabs(f.evaluate_1d(x)) / abs_int, 0.02 * f.evaluate_1d(0.0) + 1e-12)
            << "x = " << x;
    }
}

TEST_P(FilterTest, WeightedSamplesEstimateTheFilterIntegral) {
    // E[w h(offset)] = ∫ f h: h = 1 (the filter's integral, 1) and h = the quarter
    // plane x < 0.3, y < -0.2 (the product of the two 1-D integrals)
    const PixelFilter f = filter();
    const int n = 200000;
    double s1 = 0, s1sq = 0, sh = 0, shsq = 0;
    bool negative = false;
    for (int i = 0; i < n; ++i) {
        const PixelFilter::Sample s = f.sample(test::uniform2(21, uint32_t(i)));
        const double w = s.weight;
        negative |= w < 0;
        s1 += w;
        s1sq += w * w;
        const double v = (s.offset.x < 0.3f && s.offset.y < -0.2f) ? w : 0.0;
        sh += v;
        shsq += v * v;
    }
    const double m1 = s1 / n, mh = sh / n;
    const double se1 = std::sqrt(std::max(0.0, s1sq / n - m1 * m1) / n);
    const double seh = std::sqrt(std::max(0.0, shsq / n - mh * mh) / n);
    EXPECT_NEAR(m1, 1.0, 4 * se1 + 1e-4);
    EXPECT_NEAR(mh, f.integral_1d(0.3) * f.integral_1d(-0.2), 4 * seh + 1e-4);
    EXPECT_EQ(negative, GetParam() == FilterKind::mitchell);  // only mitchell has negative lobes
}

TEST_P(FilterTest, SamplingIsDeterministic) {
    const PixelFilter a = filter(), b = filter();
    for (uint32_t i = 0; i < 1000; ++i) {
        const Vec2 u = test::uniform2(22, i);
        const PixelFilter::Sample sa = a.sample(u), sb = b.sample(u);
        EXPECT_EQ(sa.offset.x, sb.offset.x);
        EXPECT_EQ(sa.offset.y, sb.offset.y);
        EXPECT_EQ(sa.weight, sb.weight);
    }
}

TEST_P(FilterTest, FootprintIsTheFilterAtThePixelCentres) {
    const PixelFilter f = filter();
    const int W = 12, H = 10;
    double mean_sum = 0;
    const int n = 4000;
    for (int i = 0; i < n; ++i) {
        const Vec2 u = test::uniform2(23, uint32_t(i));
        const Vec2 p(5.f + u.x, 4.f + u.y);  // far from the borders
        double sum = 0;
        f.footprint(p, W, H, [&](uint32_t pixel, double w) {
            const int x = int(pixel % W), y = int(pixel / W);
            const double dx = x + 0.5 - p.x, dy = y + 0.5 - p.y;
            EXPECT_NEAR(w, f.weight_1d(dx) * f.weight_1d(dy), 1e-15);  // the splat weights
            // and those within the table's accuracy of the exact f (the next test)
            EXPECT_NEAR(w, f.evaluate(dx, dy), 1e-5);
            sum += w;
        });
        mean_sum += sum / n;
    }
    EXPECT_NEAR(mean_sum, 1.0, 2e-3);  // ∫ f = 1: the weights sum to 1 on average over p
}

TEST_P(FilterTest, SplatWeightTableFollowsTheProfile) {
    // weight_1d interpolates f1 between k_weight_bins + 1 nodes on [0, r]: exact at the
    // nodes, within h²/8 max|f1''| between them (h = r / k_weight_bins; filter.h): for the
    // default radii below 2.2e-6 of the peak (mitchell's, the largest f1'' per h²), and
    // exact up to rounding for the box and the triangle (linear between nodes).
    const PixelFilter f = filter();
    const double r = f.radius();
    const double peak = std::fabs(f.evaluate_1d(0.0));
    const bool linear = GetParam() == FilterKind::box || GetParam() == FilterKind::triangle;
    const double tol = (linear ? 1e-12 : 2.5e-6) * peak;
    double worst = 0.0;
    for (int i = 0; i <= PixelFilter::k_weight_bins; ++i) {  // the nodes, both signs
        const double x = i == PixelFilter::k_weight_bins ? r : r * i / PixelFilter::k_weight_bins;
        EXPECT_NEAR(f.weight_1d(x), f.evaluate_1d(x), 1e-15 * peak) << x;
        EXPECT_EQ(f.weight_1d(-x), f.weight_1d(x)) << x;
    }
    for (uint32_t i = 0; i < 200000; ++i) {
        const double x = (2.0 * double(test::uniform2(31, i).x) - 1.0) * 1.1 * r;
        const double d = std::fabs(f.weight_1d(x) - f.evaluate_1d(x));
        worst = std::max(worst, d);
        ASSERT_LE(d, tol) << "x = " << x;
        if (std::fabs(x) > r) { ASSERT_EQ(f.weight_1d(x), 0.0) << x; }
    }
    if (!linear) { EXPECT_GT(worst, 0.0); }  // it is an interpolation, and the bound is not vacuous
    EXPECT_EQ(f.weight_1d(std::nan("")), 0.0);
}

INSTANTIATE_TEST_SUITE_P(Filters, FilterTest, ::testing::ValuesIn(k_kinds), kind_name);

TEST(PixelFilter, UnitBoxIsTheUnfilteredFilm) {
    const PixelFilter f;
    EXPECT_TRUE(f.unit_box());
    for (uint32_t i = 0; i < 100; ++i) {
        const Vec2 u = test::uniform2(24, i);
        float w = 0.f;
        const Vec2 p = f.film_position(7, 3, u, &w);
        EXPECT_EQ(p.x, 7.f + u.x);
        EXPECT_EQ(p.y, 3.f + u.y);
        EXPECT_EQ(w, 1.f);
    }
    int calls = 0;
    f.footprint(Vec2(2.7f, 1.2f), 4, 4, [&](uint32_t pixel, double w) {
        EXPECT_EQ(pixel, 1u * 4u + 2u);
        EXPECT_EQ(w, 1.0);
        ++calls;
    });
    EXPECT_EQ(calls, 1);
}

TEST(PixelFilter, BadNamesAndRadiiAreRefused) {
    EXPECT_THROW(PixelFilter::from_settings("lanczos", 0.0), SettingsError);
    EXPECT_THROW(PixelFilter::from_settings("gaussian", -1.0), SettingsError);
    EXPECT_THROW(PixelFilter::from_settings("gaussian", 4.0), SettingsError);
    EXPECT_EQ(PixelFilter::from_settings("gaussian", 0.0).radius(), 1.5);
    EXPECT_EQ(PixelFilter::from_settings("mitchell", 0.0).radius(), 2.0);
    EXPECT_EQ(PixelFilter::from_settings("blackman-harris", 2.5).radius(), 2.5);
    try {
        PixelFilter::from_settings("gaussian", 9.0);
        FAIL();
    } catch (const SettingsError& e) {
        EXPECT_NE(std::string(e.what()).find("filter_radius"), std::string::npos);
    }
}
