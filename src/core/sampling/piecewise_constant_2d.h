#pragma once
/// \file 2-D piecewise-constant distribution over [0, 1)^2 (an image's texels), sampled by
/// inverting the marginal CDF over rows (y) and then the row's conditional CDF over
/// columns (x) (pbrt's PiecewiseConstant2D).
///
/// Layout: `weights[y * nx + x]` is the weight of cell [x/nx, (x+1)/nx) x [y/ny, (y+1)/ny).
/// The density is per unit area of [0, 1)^2: pdf(p) = w(cell) / mean(w). Weights must be
/// finite and >= 0; all-zero weights give the uniform distribution.
#include "math/vec.h"

#include <cstddef>
#include <vector>

namespace cmlt {

class PiecewiseConstant2D {
public:
    PiecewiseConstant2D() = default;
    PiecewiseConstant2D(const std::vector<float>& weights, int nx, int ny);

    /// Buckets of a CDF's guide table: guide[k] is the first entry above k / k_guide, so
    /// the entry above u lies between guide[k] and guide[k + 1] for u in
    /// [k, k + 1) / k_guide and the search for it reads a few neighbouring entries
    /// instead of a binary search's cache lines across the whole CDF.
    static constexpr int k_guide = 32;

    bool empty() const { return m_nx == 0; }
    int nx() const { return m_nx; }
    int ny() const { return m_ny; }
    /// Continuous sample in [0, 1)^2 with its density; *pdf is 0 only for an empty
    /// distribution.
    Vec2 sample(const Vec2& u, float* pdf) const;
    /// Density at p (0 outside [0, 1]^2).
    float pdf(const Vec2& p) const;

private:
    /// Invert a CDF of n + 1 entries (cdf[0] = 0, cdf[n] = 1) with its guide table
    /// (k_guide + 1 entries): bin index and the offset inside it in [0, 1).
    static int invert(const double* cdf, const int* guide, int n, double u, double* frac);
    /// The guide table of a CDF of n + 1 entries into `guide`.
    static void make_guide(const double* cdf, int n, int* guide);

    int m_nx = 0, m_ny = 0;
    std::vector<float> m_w;          ///< normalised: mean 1 (so pdf = m_w)
    std::vector<double> m_marginal;  ///< ny + 1
    std::vector<double> m_cond;      ///< ny * (nx + 1)
    std::vector<int> m_marginal_guide, m_cond_guide;  ///< k_guide + 1 per CDF
};

}  // namespace cmlt
