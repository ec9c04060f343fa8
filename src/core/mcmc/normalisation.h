// cmlt — Metropolis kernels: the normalisation b = E[f*] and unbiased chain starts.
//
// b = ∫ f*(u) du over [0,1)^n is the mean of f* under independent uniform samples
// (bootstrap, then refined by every large step — NormalisationAccumulator merges).
// Chains start by resampling the bootstrap pool ∝ f* (Veach 1997 §11.3.3, start-up bias
// elimination). With b̂ the mean of the same pool, the start is exactly unbiased:
//   E[b̂ · g(X₀)] = E[ (1/N) Σ_i w_i · Σ_j (w_j / Σ_i w_i) g(x_j) ] = E[(1/N) Σ_j w_j g(x_j)]
//                = ∫ f* g,
// and since every kernel leaves π = f*/b invariant, E[b̂ · g(X_t)] = ∫ f* g for all t:
// no burn-in is needed, whatever the pool size (tested in test_normalisation.cpp).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>


namespace cmlt::mcmc {

/// Estimate of b = E[f*] with its standard error (sample sd / √n).
struct NormalisationEstimate {
  double mean = 0.0;
  double std_error = 0.0;
  std::uint64_t samples = 0;
  std::uint64_t nonzero = 0;  ///< samples with f* > 0

  double lower(double z = 1.96) const { return mean - z * std_error; }
  double upper(double z = 1.96) const { return mean + z * std_error; }
};

/// Running mean and variance of f* values (Welford; mergeable, Chan et al. 1979), so a
/// frame can start from the bootstrap and add every large step it takes.
class NormalisationAccumulator {
 public:
  /// Add one independent sample f*(u), u uniform. Invalid values (NaN, ±Inf, < 0) count as 0.
  void add(double value) {
    const double v = (value >= 0.0 && std::isfinite(value)) ? value : 0.0;
    ++m_count;
    if (v > 0.0) ++m_nonzero;
    const double delta = v - m_mean;
    m_mean += delta / double(m_count);
    m_m2 += delta * (v - m_mean);
  }

  void merge(const NormalisationAccumulator& o) {
    if (o.m_count == 0) return;
    if (m_count == 0) {
      *this = o;
      return;
    }
    const double n_a = double(m_count), n_b = double(o.m_count), n = n_a + n_b;
    const double delta = o.m_mean - m_mean;
    m_mean += delta * (n_b / n);
    m_m2 += o.m_m2 + delta * delta * (n_a * n_b / n);
    m_count += o.m_count;
    m_nonzero += o.m_nonzero;
  }

  NormalisationEstimate estimate() const {
    NormalisationEstimate e;
    e.samples = m_count;
    e.nonzero = m_nonzero;
    e.mean = m_mean;
    e.std_error = m_count > 1 ? std::sqrt(m_m2 / double(m_count - 1) / double(m_count)) : 0.0;
    return e;
  }

 private:
  std::uint64_t m_count = 0;
  std::uint64_t m_nonzero = 0;
  double m_mean = 0.0;
  double m_m2 = 0.0;
};

/// Multinomial resampling: `n` independent indices i with probability weights[i]/Σw.
/// Never returns an index of zero weight. Throws std::invalid_argument if a weight is
/// negative or not finite, or if no weight is positive (nothing to start a chain on).
template <class Rng>
std::vector<std::size_t> resample_start_indices(const std::vector<double>& weights, std::size_t n, Rng& rng) {
  std::vector<double> cumulative(weights.size());
  double total = 0.0;
  for (std::size_t i = 0; i < weights.size(); ++i) {
    const double w = weights[i];
    if (!(w >= 0.0) || !std::isfinite(w))
      throw std::invalid_argument("mcmc::resample_start_indices: weight " + std::to_string(i) +
                                  " is negative or not finite");
    total += w;
    cumulative[i] = total;
  }
  if (!(total > 0.0))
    throw std::invalid_argument("mcmc::resample_start_indices: all " + std::to_string(weights.size()) +
                                " bootstrap weights are zero; no chain can start (raise the bootstrap size)");
  std::vector<std::size_t> out(n);
  for (std::size_t c = 0; c < n; ++c) {
    const double t = rng.uniform() * total;
    // first i with cumulative[i] > t: its own weight is > 0
    std::size_t lo = 0, hi = weights.size();
    while (lo < hi) {
      const std::size_t mid = lo + (hi - lo) / 2;
      if (cumulative[mid] > t) hi = mid; else lo = mid + 1;
    }
    if (lo == weights.size()) {  // t rounded up to the total: take the last positive weight
      lo = weights.size() - 1;
      while (!(weights[lo] > 0.0)) --lo;
    }
    out[c] = lo;
  }
  return out;
}

}  // namespace cmlt::mcmc
