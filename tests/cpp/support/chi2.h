#pragma once
// Reusable Pearson chi-square goodness-of-fit helper for the sampling tests.
//
// Cells with a low expected count are pooled (sorted by expected count, merged until
// the pool reaches `min_expected`), as in pbrt-v4's bsdfs_test.cpp. A cell with an
// expected count of zero but observed samples fails outright (samples outside the
// support). The caller states the significance level; with several tests in one
// binary apply Bonferroni: alpha_per_test = alpha / number_of_tests.
#include "special_functions.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

namespace cmlt::test {

struct Chi2Result {
    double statistic = 0;
    int dof = 0;
    double p_value = 0;
    bool support_violation = false;
    std::string message;
    bool passed(double alpha) const { return !support_violation && p_value >= alpha; }
};

inline Chi2Result chi2_test(const std::vector<double>& observed, const std::vector<double>& expected,
                            double min_expected = 5.0) {
    Chi2Result r;
    std::vector<size_t> order(observed.size());
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return expected[a] < expected[b]; });
    double pool_o = 0, pool_e = 0;
    int cells = 0;
    std::ostringstream os;
    for (size_t k = 0; k < order.size(); ++k) {
        size_t i = order[k];
        if (expected[i] <= 0) {
            if (observed[i] > 0) {
                r.support_violation = true;
                os << "cell " << i << ": " << observed[i] << " samples where the pdf is 0\n";
            }
            continue;
        }
        if (expected[i] < min_expected) {
            pool_o += observed[i];
            pool_e += expected[i];
            if (pool_e >= min_expected) {
                r.statistic += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
                ++cells;
                pool_o = pool_e = 0;
            }
            continue;
        }
        double d = observed[i] - expected[i];
        r.statistic += d * d / expected[i];
        ++cells;
    }
    if (pool_e > 0) {
        r.statistic += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
        ++cells;
    }
    r.dof = std::max(1, cells - 1);
    r.p_value = chi2_sf(r.statistic, r.dof);
    os << "chi2 = " << r.statistic << ", dof = " << r.dof << ", p = " << r.p_value;
    r.message = os.str();
    return r;
}

/// Format a histogram pair (written only when a test fails).
inline std::string dump_table(const std::vector<double>& obs, const std::vector<double>& exp, int cols) {
    std::ostringstream os;
    os.precision(4);
    for (size_t i = 0; i < obs.size(); ++i) {
        os << obs[i] << "/" << exp[i] << ((int(i + 1) % cols == 0) ? "\n" : "\t");
    }
    return os.str();
}

}  // namespace cmlt::test
