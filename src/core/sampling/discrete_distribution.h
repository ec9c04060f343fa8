#pragma once
/// \file 1-D discrete distribution by inverse CDF (binary search), e.g. for light selection.
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
    size_t sample(float u, float* pmf_out = nullptr, float* u_remapped = nullptr) const;

private:
    std::vector<float> m_pmf;
    std::vector<double> m_cdf;  // size n+1, m_cdf[n] == 1
};

}  // namespace cmlt
