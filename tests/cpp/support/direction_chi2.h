#pragma once
/// \file Chi-square goodness-of-fit test for direction samplers (BSDFs, lights, cameras).
///
/// Same plan as Mitsuba 3's `chi2.py` and pbrt-v4's `bsdfs_test.cpp`:
///  1. draw N directions with the sampler and histogram them over (theta, phi) bins of the
///     full sphere (transmission lands in the lower half);
///  2. integrate the sampler's pdf over every bin with nested adaptive Simpson quadrature
///     (integrand pdf(theta, phi) sin(theta)) to get the expected counts;
///  3. pool cells with expected count < 5 (sorted ascending, merged until the pool reaches 5),
///     fail outright on samples in a cell whose expected count is 0;
///  4. Pearson statistic, p-value from the chi^2 distribution (regularised upper incomplete
///     gamma, implemented here), compared with a significance level that the caller
///     Bonferroni-corrects for the number of cases it runs;
///  5. the same statistic on a coarse table (blocks of coarse_factor^2 cells): Pearson's
///     statistic over thousands of cells dilutes smooth errors (a +-3 % tilt of the Lambert
///     pdf gives z ~ 2 over 8000 cells but is obvious over 200);
///  6. a test of the total: the number of valid samples is Binomial(N, I) where I is the pdf's
///     integral over the sphere (a 4 % scale error of a pdf gave p ~ 1e-3 in the fine table,
///     ~40 sigma here).
///     The significance level is split evenly between the three sub-tests.
/// On failure the observed / expected tables are written to a text file (never on success).
///
/// The harness is header-only and independent of GoogleTest.
#include "special_functions.h"

#include "math/safe_math.h"
#include "math/vec.h"
#include "sampling/rng.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numeric>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace cmlt::test {

// ---------------------------------------------------------------------------------------------
// Quadrature
// ---------------------------------------------------------------------------------------------

namespace detail {
inline double simpson_recurse(const std::function<double(double)>& f, double a, double b,
                              double c, double fa, double fb, double fc, double whole, double eps,
                              int depth, int min_depth) {
    double d = 0.5 * (a + b), e = 0.5 * (b + c);
    double fd = f(d), fe = f(e);
    double left = (b - a) / 6.0 * (fa + 4.0 * fd + fb);
    double right = (c - b) / 6.0 * (fb + 4.0 * fe + fc);
    double both = left + right;
    if (depth <= 0 || (min_depth <= 0 && std::fabs(both - whole) <= 15.0 * eps))
        return both + (both - whole) / 15.0;  // Richardson extrapolation
    return simpson_recurse(f, a, d, b, fa, fd, fb, left, 0.5 * eps, depth - 1, min_depth - 1) +
           simpson_recurse(f, b, e, c, fb, fe, fc, right, 0.5 * eps, depth - 1, min_depth - 1);
}
}  // namespace detail

/// Adaptive Simpson on [x0, x1] with absolute tolerance `eps`. The interval is always split
/// `min_depth` times first, so that a narrow peak between the first five nodes is not missed.
inline double adaptive_simpson(const std::function<double(double)>& f, double x0, double x1,
                               double eps = 1e-9, int max_depth = 10, int min_depth = 2) {
    double a = x0, b = 0.5 * (x0 + x1), c = x1;
    double fa = f(a), fb = f(b), fc = f(c);
    double whole = (c - a) / 6.0 * (fa + 4.0 * fb + fc);
    return detail::simpson_recurse(f, a, b, c, fa, fb, fc, whole, eps, max_depth, min_depth);
}

/// Nested adaptive Simpson over [x0, x1] x [y0, y1].
inline double adaptive_simpson_2d(const std::function<double(double, double)>& f, double x0,
                                  double x1, double y0, double y1, double eps = 1e-9,
                                  int max_depth = 10, int min_depth = 2) {
    auto inner = [&](double y) {
        return adaptive_simpson([&](double x) { return f(x, y); }, x0, x1, eps / (y1 - y0),
                                max_depth, min_depth);
    };
    return adaptive_simpson(inner, y0, y1, eps, max_depth, min_depth);
}

// ---------------------------------------------------------------------------------------------
// The test
// ---------------------------------------------------------------------------------------------

struct Chi2Options {
    int theta_res = 96;          ///< bins over theta in [0, pi] (z = 0 must be a bin edge of
                                 ///< both tables: theta_res / coarse_factor even)
    int phi_res = 192;           ///< bins over phi in [0, 2 pi)
    int coarse_factor = 8;       ///< the coarse table merges coarse_factor^2 fine cells
    int sample_count = 1000000;  ///< sampler calls (failed samples count as missing mass)
    double min_expected = 5.0;   ///< pool cells with fewer expected samples
    double significance = 0.01;  ///< per-test level, already Bonferroni-corrected by the caller
    double integration_eps = 1e-9;  ///< absolute tolerance of the per-bin pdf integral
    uint64_t seed = 0x5eed;
    uint32_t stream_id = 0;      ///< distinguishes cases that share a seed
    std::string name = "chi2";   ///< used for the dump file name
};

struct Chi2Outcome {
    bool passed = false;
    double p_value = 0.0;
    double statistic = 0.0;
    int dof = 0;
    int cells = 0;            ///< cells after pooling
    double pdf_integral = 0;  ///< integral of the pdf over the sphere
    double valid_fraction = 0;  ///< fraction of sampler calls that returned a direction
    double coarse_statistic = 0;  ///< Pearson statistic of the coarsened table
    int coarse_dof = 0;
    double coarse_p_value = 1;
    double total_z = 0;         ///< (valid - N I) / sd: binomial test of the total mass
    double total_p_value = 1;   ///< two-sided p-value of total_z
    std::string message;      ///< reason for failure, summary otherwise
    std::string dump_path;    ///< tables written here on failure
};

/// Chi^2 test of a direction sampler against its pdf over the unit sphere.
/// `sample(u1, u2)` returns a unit direction or nullopt; `pdf(w)` is its solid-angle density.
class SphericalChi2Test {
public:
    using SampleFn = std::function<std::optional<Vec3>(float u1, const Vec2& u2)>;
    using PdfFn = std::function<double(const Vec3& w)>;

    SphericalChi2Test(SampleFn sample, PdfFn pdf, Chi2Options options)
        : m_sample(std::move(sample)), m_pdf(std::move(pdf)), m_opt(std::move(options)) {}

    Chi2Outcome run() {
        tabulate_observed();
        tabulate_expected();
        return compare();
    }

    const std::vector<double>& observed() const { return m_observed; }
    const std::vector<double>& expected() const { return m_expected; }

private:
    double theta_step() const { return k_pi_d / m_opt.theta_res; }
    double phi_step() const { return 2.0 * k_pi_d / m_opt.phi_res; }

    void tabulate_observed() {
        m_observed.assign(size_t(m_opt.theta_res) * m_opt.phi_res, 0.0);
        m_valid = 0;
        m_bad_samples = 0;
        for (int i = 0; i < m_opt.sample_count; ++i) {
            PixelSampler rng(m_opt.seed, m_opt.stream_id, uint32_t(i), RngStream::test);
            float u1 = rng.get1d();
            Vec2 u2 = rng.get2d();
            std::optional<Vec3> w = m_sample(u1, u2);
            if (!w) continue;
            double x = w->x, y = w->y, z = w->z;
            double len = std::sqrt(x * x + y * y + z * z);
            if (!(std::fabs(len - 1.0) < 1e-3)) {  // not a unit direction: count as outside
                ++m_bad_samples;
                continue;
            }
            double theta = std::acos(std::clamp(z / len, -1.0, 1.0));
            double phi = std::atan2(y, x);
            if (phi < 0.0) phi += 2.0 * k_pi_d;
            int it = std::min(int(theta / theta_step()), m_opt.theta_res - 1);
            int ip = std::min(int(phi / phi_step()), m_opt.phi_res - 1);
            m_observed[size_t(it) * m_opt.phi_res + ip] += 1.0;
            ++m_valid;
        }
    }

    void tabulate_expected() {
        m_expected.assign(m_observed.size(), 0.0);
        auto integrand = [&](double phi, double theta) {
            double st = std::sin(theta);
            Vec3 w(float(st * std::cos(phi)), float(st * std::sin(phi)), float(std::cos(theta)));
            double p = m_pdf(w);
            return std::isfinite(p) ? p * st : 0.0;
        };
        double total = 0.0;
        for (int it = 0; it < m_opt.theta_res; ++it) {
            double t0 = it * theta_step(), t1 = t0 + theta_step();
            for (int ip = 0; ip < m_opt.phi_res; ++ip) {
                double p0 = ip * phi_step(), p1 = p0 + phi_step();
                double v = adaptive_simpson_2d(integrand, p0, p1, t0, t1, m_opt.integration_eps);
                v = std::max(v, 0.0);
                m_expected[size_t(it) * m_opt.phi_res + ip] = v * m_opt.sample_count;
                total += v;
            }
        }
        m_pdf_integral = total;
    }

    struct Pearson {
        double statistic = 0.0;
        int cells = 0;
        std::string error;  ///< non-empty: samples where the expected count is 0
    };

    /// Pearson's statistic with low-expected cells pooled (ascending order, pool grown until
    /// it holds at least `min_expected`).
    Pearson pearson(const std::vector<double>& obs, const std::vector<double>& exp,
                    int phi_res) const {
        Pearson r;
        std::vector<size_t> order(exp.size());
        std::iota(order.begin(), order.end(), size_t(0));
        std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return exp[a] < exp[b]; });
        double pooled_obs = 0.0, pooled_exp = 0.0;
        for (size_t idx : order) {
            double e = exp[idx], o = obs[idx];
            if (e <= 0.0) {
                if (o > 0.0 && r.error.empty()) {
                    std::ostringstream os;
                    os << o << " samples in cell (theta " << idx / phi_res << ", phi "
                       << idx % phi_res << ") whose pdf integral is 0";
                    r.error = os.str();
                }
                continue;
            }
            if (e < m_opt.min_expected || (pooled_exp > 0.0 && pooled_exp < m_opt.min_expected)) {
                pooled_obs += o;
                pooled_exp += e;
                continue;
            }
            r.statistic += sqr_d(o - e) / e;
            ++r.cells;
        }
        if (pooled_exp > 0.0) {
            r.statistic += sqr_d(pooled_obs - pooled_exp) / pooled_exp;
            ++r.cells;
        }
        return r;
    }

    /// Sum `factor` x `factor` blocks of a theta-major table.
    std::vector<double> coarsen(const std::vector<double>& t, int factor) const {
        int tr = m_opt.theta_res / factor, pr = m_opt.phi_res / factor;
        std::vector<double> c(size_t(tr) * pr, 0.0);
        for (int it = 0; it < m_opt.theta_res; ++it)
            for (int ip = 0; ip < m_opt.phi_res; ++ip)
                c[size_t(it / factor) * pr + ip / factor] += t[size_t(it) * m_opt.phi_res + ip];
        return c;
    }

    Chi2Outcome compare() {
        Chi2Outcome out;
        out.pdf_integral = m_pdf_integral;
        out.valid_fraction = double(m_valid) / m_opt.sample_count;
        if (m_bad_samples > 0) {
            out.message = std::to_string(m_bad_samples) + " samples were not unit vectors";
            return fail(out);
        }
        // (a) fine table: sensitive to misplaced or too-narrow/too-wide sharp features.
        Pearson fine = pearson(m_observed, m_expected, m_opt.phi_res);
        if (!fine.error.empty()) {
            out.message = fine.error;
            return fail(out);
        }
        out.cells = fine.cells;
        out.dof = fine.cells - 1;
        out.statistic = fine.statistic;
        out.p_value = chi2_sf(fine.statistic, out.dof);
        // (b) coarse table: the fine statistic dilutes a smooth few-percent shape error over
        // thousands of degrees of freedom; blocks of cells see it.
        const int cf = m_opt.coarse_factor;
        Pearson coarse = pearson(coarsen(m_observed, cf), coarsen(m_expected, cf), m_opt.phi_res / cf);
        out.coarse_dof = coarse.cells - 1;
        out.coarse_statistic = coarse.statistic;
        out.coarse_p_value = chi2_sf(coarse.statistic, out.coarse_dof);
        // (c) total mass: valid count ~ Binomial(N, I). The variance gets a floor of
        // (1e-4 N)^2 for the quadrature error of I (<= integration_eps per bin).
        const double n = m_opt.sample_count, mass = std::clamp(m_pdf_integral, 0.0, 1.0);
        const double sd = std::sqrt(n * mass * (1.0 - mass) + sqr_d(1e-4 * n));
        out.total_z = (double(m_valid) - n * m_pdf_integral) / sd;
        out.total_p_value = std::erfc(std::fabs(out.total_z) / std::sqrt(2.0));

        const double level = m_opt.significance / 3.0;  // split between the three sub-tests
        std::ostringstream os;
        os << "fine chi2 = " << fine.statistic << " (dof " << out.dof << ", p " << out.p_value
           << "); coarse chi2 = " << coarse.statistic << " (dof " << out.coarse_dof << ", p "
           << out.coarse_p_value << "); total: pdf integral " << m_pdf_integral
           << ", valid fraction " << out.valid_fraction << ", z " << out.total_z << " (p "
           << out.total_p_value << "); level " << level << " each";
        out.message = os.str();
        if (out.dof < 1 || !(out.p_value >= level) || !(out.total_p_value >= level) ||
            (out.coarse_dof >= 1 && !(out.coarse_p_value >= level)))
            return fail(out);
        out.passed = true;
        return out;
    }

    Chi2Outcome fail(Chi2Outcome out) {
        out.passed = false;
        out.dump_path = dump_tables(out.message);
        return out;
    }

    std::string dump_tables(const std::string& message) const {
        std::error_code ec;
        std::filesystem::path dir = std::filesystem::temp_directory_path(ec);
        if (ec) dir = ".";
        std::filesystem::path path = dir / ("cmlt_chi2_" + m_opt.name + ".txt");
        std::ofstream f(path);
        if (!f) return "";
        f << "# " << m_opt.name << ": " << message << "\n";
        f << "# rows: theta bins over [0, pi] (" << m_opt.theta_res << "), columns: phi bins over"
          << " [0, 2pi) (" << m_opt.phi_res << "), samples: " << m_opt.sample_count << "\n";
        auto table = [&](const char* title, const std::vector<double>& t) {
            f << "\n## " << title << "\n";
            for (int it = 0; it < m_opt.theta_res; ++it) {
                for (int ip = 0; ip < m_opt.phi_res; ++ip)
                    f << (ip ? " " : "") << t[size_t(it) * m_opt.phi_res + ip];
                f << "\n";
            }
        };
        table("observed", m_observed);
        table("expected", m_expected);
        return path.string();
    }

    static double sqr_d(double x) { return x * x; }
    static constexpr double k_pi_d = 3.14159265358979323846;

    SampleFn m_sample;
    PdfFn m_pdf;
    Chi2Options m_opt;
    std::vector<double> m_observed, m_expected;
    double m_pdf_integral = 0.0;
    long m_valid = 0, m_bad_samples = 0;
};

/// Per-test significance for `num_tests` tests at family-wise level `alpha` (Bonferroni).
inline double bonferroni(double alpha, int num_tests) { return alpha / std::max(1, num_tests); }

}  // namespace cmlt::test
