#include "sampling/discrete_distribution.h"

#include "math/safe_math.h"
#include "util/error.h"

#include <algorithm>
#include <cmath>

namespace cmlt {

DiscreteDistribution::DiscreteDistribution(const std::vector<double>& weights) {
    size_t n = weights.size();
    if (n == 0) return;
    double total = 0;
    for (double w : weights) {
        CMLT_CHECK_MSG(std::isfinite(w) && w >= 0, "weight " << w);
        total += w;
    }
    m_cdf.resize(n + 1);
    m_pmf.resize(n);
    m_cdf[0] = 0;
    for (size_t i = 0; i < n; ++i) {
        double p = total > 0 ? weights[i] / total : 1.0 / double(n);
        m_pmf[i] = float(p);
        m_cdf[i + 1] = m_cdf[i] + p;
    }
    for (size_t i = 1; i <= n; ++i) m_cdf[i] /= m_cdf[n];
    m_cdf[n] = 1.0;
}

size_t DiscreteDistribution::search(float u, float* pmf_out, float* u_remapped) const {
    CMLT_DCHECK(!m_pmf.empty());
    // First index i with cdf[i+1] > u, skipping zero-probability bins.
    auto it = std::upper_bound(m_cdf.begin() + 1, m_cdf.end(), double(u));
    size_t i = std::min<size_t>(size_t(it - m_cdf.begin()) - 1, m_pmf.size() - 1);
    while (m_pmf[i] == 0.f && i + 1 < m_pmf.size()) ++i;
    if (pmf_out) *pmf_out = m_pmf[i];
    if (u_remapped) {
        double w = m_cdf[i + 1] - m_cdf[i];
        double r = w > 0 ? (double(u) - m_cdf[i]) / w : 0.0;
        *u_remapped = float(std::clamp(r, 0.0, double(k_one_minus_eps)));
    }
    return i;
}

}  // namespace cmlt
