#pragma once
// Special functions of the statistical tests (one copy for every harness: support/chi2.h,
// support/direction_chi2.h, mcmc/toy_targets.h).
#include <algorithm>
#include <cmath>

namespace cmlt::test {

/// Regularised upper incomplete gamma function Q(a, x) = Gamma(a, x) / Gamma(a), a > 0, x >= 0.
/// Series for x < a + 1, Lentz continued fraction otherwise (Numerical Recipes 6.2).
inline double gamma_q(double a, double x) {
    if (!(a > 0.0) || std::isnan(x)) return std::nan("");
    if (x <= 0.0) return 1.0;
    if (std::isinf(x)) return 0.0;
    const double log_prefactor = -x + a * std::log(x) - std::lgamma(a);
    constexpr double eps = 1e-15, tiny = 1e-300;
    if (x < a + 1.0) {
        // P(a, x) = x^a e^-x / Gamma(a + 1) * sum_n x^n / ((a+1)...(a+n))
        double ap = a, del = 1.0 / a, sum = del;
        for (int n = 0; n < 10000; ++n) {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if (std::fabs(del) < std::fabs(sum) * eps) break;
        }
        return std::clamp(1.0 - sum * std::exp(log_prefactor), 0.0, 1.0);
    }
    double b = x + 1.0 - a, c = 1.0 / tiny, d = 1.0 / b, h = d;
    for (int i = 1; i < 10000; ++i) {
        double an = -i * (i - a);
        b += 2.0;
        d = an * d + b;
        if (std::fabs(d) < tiny) d = tiny;
        c = b + an / c;
        if (std::fabs(c) < tiny) c = tiny;
        d = 1.0 / d;
        double del = d * c;
        h *= del;
        if (std::fabs(del - 1.0) < eps) break;
    }
    return std::clamp(std::exp(log_prefactor) * h, 0.0, 1.0);
}

/// P(X >= statistic) for X ~ chi^2 with `dof` degrees of freedom.
inline double chi2_sf(double statistic, int dof) {
    if (dof <= 0) return 1.0;
    return gamma_q(0.5 * dof, 0.5 * statistic);
}

}  // namespace cmlt::test
