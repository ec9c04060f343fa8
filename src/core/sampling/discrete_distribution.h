#pragma once
/// \file 1-D discrete distribution by inverse CDF (binary search), e.g. for light selection.
#include "math/safe_math.h"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace cmlt {

class DiscreteDistribution {
public:
    DiscreteDistribution() = default;
    /// Weights must be finite and >= 0. If all are zero the distribution is uniform.
    explicit DiscreteDistribution(const std::vector<double>& weights);

    size_t size() const { return m_pmf.size(); }
    bool empty() const { return m_pmf.empty(); }
    float pmf(size_t i) const { return i < m_pmf.size() ? m_pmf[i] : 0.f; }
    /// Sample an index; `u_remapped` (optional) receives u rescaled to [0,1) inside the bin.
    size_t sample(float u, float* pmf_out = nullptr, float* u_remapped = nullptr) const {
        // one bin (a scene with one light): the search's answer, without the search
        if (m_pmf.size() != 1) return search(u, pmf_out, u_remapped);
        if (pmf_out) *pmf_out = m_pmf[0];
        if (u_remapped) *u_remapped = float(std::clamp(double(u), 0.0, double(k_one_minus_eps)));
        return 0;
    }

private:
    size_t search(float u, float* pmf_out, float* u_remapped) const;

    std::vector<float> m_pmf;
    std::vector<double> m_cdf;  // size n+1, m_cdf[n] == 1
};

}  // namespace cmlt
