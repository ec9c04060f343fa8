// Toy targets with exactly known bin integrals, exact samplers, and the statistics the
// MCMC kernel tests need (normal quantiles, chi-square tail, per-bin z-tests).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "special_functions.h"

#include "mcmc/mcmc.h"
#include "test_rng.h"
#include "toy_chains.h"

namespace cmlt::mcmc::testing {

using Vec = std::vector<double>;

/// Offset added to every statistical test's seed: CMLT_TEST_SEED_OFFSET=<n> re-runs the
/// suite on fresh random numbers (to check the stated false-alarm rates). Default 0.
inline std::uint64_t seed_offset() {
  static const std::uint64_t offset = [] {
    const char* env = std::getenv("CMLT_TEST_SEED_OFFSET");
    return env ? std::strtoull(env, nullptr, 10) * 1000003ull : 0ull;
  }();
  return offset;
}

/// ∫_a^b exp(−(x−m)²/(2s²)) dx.
inline double gauss_integral(double a, double b, double m, double s) {
  const double k = 1.0 / (s * std::sqrt(2.0));
  return s * std::sqrt(M_PI / 2.0) * (std::erf((b - m) * k) - std::erf((a - m) * k));
}

/// 1-D "two bumps on a floor" on [0,1):
/// f(x) = 0.2 + exp(−(x−0.3)²/(2·0.03²)) + 0.5·exp(−(x−0.7)²/(2·0.05²)).
struct TwoBumps {
  static constexpr std::size_t k_dims = 1;
  static double eval(double x) {
    const double d1 = x - 0.3, d2 = x - 0.7;
    return 0.2 + std::exp(-d1 * d1 / (2 * 0.03 * 0.03)) + 0.5 * std::exp(-d2 * d2 / (2 * 0.05 * 0.05));
  }
  template <class State>
  double operator()(const State& u) const { return eval(u[0]); }
  static double integral(double a, double b) {
    return 0.2 * (b - a) + gauss_integral(a, b, 0.3, 0.03) + 0.5 * gauss_integral(a, b, 0.7, 0.05);
  }
  static double envelope() { return 1.25; }  // max f ≈ 1.2 at x = 0.3
};

/// 2-D checkerboard (4×4 cells) with a Gaussian bump, on [0,1)²:
/// f(x, y) = c(x, y) · (1 + h·exp(−|p − p₀|²/(2s²))), c = 1 on even cells, `odd` on odd
/// cells. With odd = 0 half of the domain has f = 0 (the zero-region target).
struct CheckerBump {
  static constexpr std::size_t k_dims = 2;
  double odd = 0.25;
  double bx = 0.7, by = 0.3, s = 0.06, h = 3.0;

  double cell_factor(double x, double y) const {
    const int i = std::min(3, int(x * 4.0)), j = std::min(3, int(y * 4.0));
    return ((i + j) % 2 == 0) ? 1.0 : odd;
  }
  double eval(double x, double y) const {
    const double dx = x - bx, dy = y - by;
    return cell_factor(x, y) * (1.0 + h * std::exp(-(dx * dx + dy * dy) / (2 * s * s)));
  }
  template <class State>
  double operator()(const State& u) const { return eval(u[0], u[1]); }
  /// Exact integral over [x0,x1)×[y0,y1) lying inside one checker cell.
  double integral(double x0, double x1, double y0, double y1) const {
    const double c = cell_factor(0.5 * (x0 + x1), 0.5 * (y0 + y1));
    return c * ((x1 - x0) * (y1 - y0) + h * gauss_integral(x0, x1, bx, s) * gauss_integral(y0, y1, by, s));
  }
  double envelope() const { return 1.0 + h; }
};

/// Binning of [0,1)^d into `per_axis`^d equal bins (row-major), with exact bin integrals.
template <class Target>
struct Binned {
  Target target;
  std::size_t per_axis;

  std::size_t bins() const { return Target::k_dims == 1 ? per_axis : per_axis * per_axis; }
  template <class State>
  std::size_t bin(const State& u) const {
    const auto axis = [&](double v) { return std::min(per_axis - 1, std::size_t(v * double(per_axis))); };
    return Target::k_dims == 1 ? axis(u[0]) : axis(u[1]) * per_axis + axis(u[0]);
  }
  /// ∫_bin f for every bin.
  std::vector<double> bin_integrals() const {
    std::vector<double> out(bins());
    const double w = 1.0 / double(per_axis);
    for (std::size_t b = 0; b < bins(); ++b) {
      if constexpr (Target::k_dims == 1) {
        out[b] = target.integral(b * w, (b + 1) * w);
      } else {
        const std::size_t ix = b % per_axis, iy = b / per_axis;
        out[b] = target.integral(ix * w, (ix + 1) * w, iy * w, (iy + 1) * w);
      }
    }
    return out;
  }
  double total() const {
    double t = 0;
    for (double v : bin_integrals()) t += v;
    return t;
  }
  /// Bin probabilities under π = f / ∫f.
  std::vector<double> probabilities() const {
    auto p = bin_integrals();
    const double t = total();
    for (double& v : p) v /= t;
    return p;
  }
  /// Exact draw from π by rejection from the uniform density.
  template <class Rng>
  Vec exact_draw(Rng& rng) const {
    Vec u(Target::k_dims);
    for (;;) {
      for (auto& v : u) v = rng.uniform();
      if (rng.uniform() * target.envelope() < target(u)) return u;
    }
  }
};

/// Upper-tail normal quantile: z with P(Z > z) = p (bisection on erfc, |error| < 1e-12).
inline double normal_upper_quantile(double p) {
  double lo = -40.0, hi = 40.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (0.5 * std::erfc(mid / std::sqrt(2.0)) > p) lo = mid; else hi = mid;
  }
  return 0.5 * (lo + hi);
}

/// Q(a, x), the regularised upper incomplete gamma function (support/special_functions.h).
using cmlt::test::gamma_q;

/// Pearson chi-square of observed counts against expected probabilities. Cells with
/// expected count below 5 are pooled into one cell; cells with p = 0 are left out (their
/// counts are checked by the caller). Returns the p-value; writes statistic and dof.
inline double chi_square_p_value(const std::vector<double>& counts, const std::vector<double>& probs,
                                 double* statistic = nullptr, int* dof = nullptr) {
  double n = 0;
  for (std::size_t i = 0; i < counts.size(); ++i)
    if (probs[i] > 0) n += counts[i];
  double chi2 = 0, pooled_obs = 0, pooled_exp = 0;
  int cells = 0;
  for (std::size_t i = 0; i < counts.size(); ++i) {
    if (!(probs[i] > 0)) continue;
    const double e = n * probs[i];
    if (e < 5) {
      pooled_obs += counts[i];
      pooled_exp += e;
      continue;
    }
    chi2 += (counts[i] - e) * (counts[i] - e) / e;
    ++cells;
  }
  if (pooled_exp > 0) {
    chi2 += (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
    ++cells;
  }
  const int df = std::max(1, cells - 1);
  if (statistic) *statistic = chi2;
  if (dof) *dof = df;
  return gamma_q(0.5 * df, 0.5 * chi2);
}

/// Per-bin mean and standard error over independent replicate vectors.
struct BinMeans {
  std::vector<double> sum, sum_sq;
  std::size_t n = 0;
  explicit BinMeans(std::size_t bins) : sum(bins, 0.0), sum_sq(bins, 0.0) {}
  void add(const std::vector<double>& v) {
    for (std::size_t b = 0; b < v.size(); ++b) {
      sum[b] += v[b];
      sum_sq[b] += v[b] * v[b];
    }
    ++n;
  }
  double mean(std::size_t b) const { return sum[b] / double(n); }
  double std_error(std::size_t b) const {
    const double m = mean(b);
    const double var = std::max(0.0, (sum_sq[b] - double(n) * m * m) / double(n - 1));
    return std::sqrt(var / double(n));
  }
  /// Largest |z| over bins against `expected` (bins with zero SE and zero deviation skipped;
  /// zero SE with a deviation gives +inf). Writes the worst bin.
  double max_abs_z(const std::vector<double>& expected, std::size_t* worst = nullptr) const {
    double zmax = 0;
    for (std::size_t b = 0; b < sum.size(); ++b) {
      const double d = mean(b) - expected[b], se = std_error(b);
      const double z = se > 0 ? std::abs(d) / se : (d != 0 ? HUGE_VAL : 0.0);
      if (z > zmax) {
        zmax = z;
        if (worst) *worst = b;
      }
    }
    return zmax;
  }
};

}  // namespace cmlt::mcmc::testing
