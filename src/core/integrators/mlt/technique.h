#pragma once
/// \file The technique of a multiplexed-MLT state (Hachisuka et al. 2014): path depth and
/// BDPT strategy (s, t), chosen from two primary samples of their own — the connection
/// stream's dimension 0 (slots 0 and 1 of stream 2, MltSampler layout):
///   depth = inverse CDF of the depth pmf at u0,  (s, t) = choose_strategy(depth, u1)
/// so the pmf of a technique is p(depth) · p(s, t | depth), and
///   L(u) = C_st(u) / (p(depth) p(s,t | depth))
/// (C_st: BdptTracer::evaluate_strategy, MIS-weighted) satisfies
///   E[L · 1{pixel j}] = I_j / (W·H)
/// for every depth in [0, max_depth] — the same normalisation as PT's estimator for a
/// uniform film position, so PSSMLT's b · histogram / mutations-per-pixel is unchanged.
///
/// Depth pmf: geometric with a floor, p(d) ∝ max(ρ^(d − min_depth), k_depth_floor) on
/// [min_depth, max_depth] (min_depth 0 unless a direct pass renders the short paths),
/// ρ = k_depth_ratio. Any pmf with
/// p(d) > 0 for every d gives the same image (f* carries 1/p(d)); it only shapes where
/// *large steps* go (an independence proposal is best ∝ the target's depth marginal
/// b_d, which decays roughly geometrically with the albedo) and what a proposal costs
/// (depth d traces d + 2 vertices; strategies have no Russian roulette). The time a
/// chain spends at depth d is b_d / b whatever the pmf. A uniform pmf over
/// [0, max_depth] (pbrt's per-depth bootstrap) would spend most large steps on depths
/// ≥ 10 at the default max_depth = 64; pbrt caps MLT's depth at 5 instead, which biases
/// the image against PT/BDPT at the same max_depth — we keep the full range. The floor
/// keeps every depth's interval of u0 wide (≥ 2.5e-5 at max_depth 64) against the float
/// resolution of the samples the path routines read (u0 is read as a float: ulp ≤ 6e-8
/// near 1, a relative pmf error ≤ 0.3% on depths > 32 only, whose energy is negligible).
#include "integrators/bdpt/bdpt_tracer.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace cmlt::mlt {

/// Ratio of the geometric depth pmf (see the file comment).
inline constexpr double k_depth_ratio = 0.75;
/// Floor of the unnormalised depth weights (ρ^d reaches it at d ≈ 32).
inline constexpr double k_depth_floor = 1e-4;
/// Sampler dimensions (of the connection stream) that hold the technique: dimension 0,
/// two slots (u0 → depth, u1 → strategy). BDPT's own connection numbers follow.
inline constexpr uint32_t k_technique_dimensions = 1;

class TechniqueSampler {
public:
    /// Depths in [min_depth, max_depth] (min_depth ≤ max_depth; the Metropolis
    /// integrators use min_depth 2 when their direct pass renders depths 0 and 1).
    explicit TechniqueSampler(int max_depth, int min_depth = 0)
        : m_cdf(size_t(std::max(max_depth, 0)) + 2, 0.0), m_min_depth(std::min(std::max(min_depth, 0), max_depth)) {
        double w = 1.0, sum = 0.0;
        for (int d = 0; d <= max_depth; ++d) {
            if (d >= m_min_depth) {
                sum += std::max(w, k_depth_floor);
                w *= k_depth_ratio;
            }
            m_cdf[size_t(d) + 1] = sum;
        }
        for (double& c : m_cdf) c /= sum;
        m_cdf.back() = 1.0;
    }

    int min_depth() const { return m_min_depth; }

    int max_depth() const { return int(m_cdf.size()) - 2; }

    /// Probability of depth d (0 outside [0, max_depth]).
    double depth_pmf(int d) const {
        if (d < 0 || d > max_depth()) return 0.0;
        return m_cdf[size_t(d) + 1] - m_cdf[size_t(d)];
    }

    /// Depth for u ∈ [0, 1): the d with cdf[d] ≤ u < cdf[d+1].
    int depth(double u) const {
        const auto it = std::upper_bound(m_cdf.begin() + 1, m_cdf.end(), u);
        return std::max(std::min(int(it - m_cdf.begin()) - 1, max_depth()), m_min_depth);
    }

    /// Choose depth and (s, t) from the two technique samples; returns the technique's
    /// probability p(depth) · p(s, t | depth) (> 0).
    double choose(float u0, float u1, int* depth, int* s, int* t) const {
        *depth = this->depth(double(u0));
        BdptTracer::choose_strategy(*depth, u1, s, t);  // uniform over the strategies
        const double p_st = 1.0 / double(BdptTracer::strategy_count(*depth));
        return depth_pmf(*depth) * p_st;
    }

private:
    std::vector<double> m_cdf;  ///< m_cdf[d] = P(depth < d), m_cdf[max+1] = 1
    int m_min_depth = 0;
};

}  // namespace cmlt::mlt
