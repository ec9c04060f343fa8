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
///
/// The camera technique (RenderSettings::mlt_camera_technique = q > 0): u0 < q picks it,
/// else the depth comes from (u0 − q)/(1 − q) as above. It evaluates, along one camera
/// subpath with Russian roulette, every strategy with s ≤ 1 of every depth in
/// [min_depth, max_depth] — what a path tracer with next-event estimation samples
/// (BdptTracer::evaluate_camera_strategies). A strategy (d, s, t) with s ≤ 1 is then
/// evaluated by two techniques: the camera technique with probability q and its own
/// with (1 − q) p(d) p(s, t | d). Both weight its MIS-weighted contribution C_st by one
/// over their sum (one-sample MIS over the techniques, balance heuristic),
///   p_eff(d, s) = q + (1 − q) p(d) p(s, t | d)     (s ≤ 1),
///   p_eff(d, s) = (1 − q) p(d) p(s, t | d)         (s ≥ 2),
/// so E[L] sums every strategy's C_st once, as before (the MIS weights w_st of both
/// techniques are the same functions of the path: Russian roulette is not in BDPT's
/// densities, only in the camera technique's throughput). Why: a path that only s ≤ 1
/// samples — a caustic seen through a mirror or glass, L S S D S E, only s = 0 — gets
/// f* = C / (p(d) p(s, t | d)), ~70 times its path-traced contribution at depth 5, and
/// is found ~70 times less often by the bootstrap and the large steps than a path
/// tracer finds it: a heavy tail of b̂ (sequences/hard/caustic_sds: one render in ~18
/// had b̂ 2.5 times too high and half its chains on one glint). With q > 0 its f* is at
/// most C / q and the camera technique finds it as often as a path tracer does.
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
    /// `camera`: q, the probability of the camera technique (file comment), in [0, 1).
    explicit TechniqueSampler(int max_depth, int min_depth = 0, double camera = 0.0)
        : m_cdf(size_t(std::max(max_depth, 0)) + 2, 0.0), m_min_depth(std::min(std::max(min_depth, 0), max_depth)),
          m_camera(std::min(std::max(camera, 0.0), 0.999)) {
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
        if (m_camera > 0.0) {
            m_camera_weights.assign(2 * (size_t(std::max(max_depth, 0)) + 1), 0.f);
            for (int d = m_min_depth; d <= max_depth; ++d)
                for (int s = 0; s <= 1; ++s)  // (1, 1) is no strategy of depth 0
                    m_camera_weights[size_t(2 * d + s)] = (d == 0 && s == 1) ? 0.f : float(1.0 / strategy_pmf(d, s));
        }
    }

    /// q: the probability of the camera technique.
    double camera_probability() const { return m_camera; }
    /// Whether u0 picks the camera technique.
    bool camera(float u0) const { return double(u0) < m_camera; }
    /// The camera technique's weight 1 / p_eff(d, s) of strategy (d, s), s ∈ {0, 1},
    /// at [2 d + s]; 0 for depths below min_depth and for (1, 1). Empty when q = 0.
    const std::vector<float>& camera_weights() const { return m_camera_weights; }

    /// p_eff(d, s) of the file comment: the probability that strategy (d, s) is
    /// evaluated by one state (its own technique, or the camera technique for s ≤ 1).
    double strategy_pmf(int d, int s) const {
        const double own = (1.0 - m_camera) * depth_pmf(d) / double(BdptTracer::strategy_count(d));
        return s <= 1 && d >= m_min_depth ? m_camera + own : own;
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

    /// Choose depth and (s, t) from the two technique samples; returns the strategy's
    /// p_eff (file comment; p(depth) · p(s, t | depth) when q = 0), > 0. The camera
    /// technique (u0 < q) sets depth, s and t to −1 and returns 1 (its weights are
    /// per strategy: camera_weights).
    double choose(float u0, float u1, int* depth, int* s, int* t) const {
        if (camera(u0)) {
            *depth = *s = *t = -1;
            return 1.0;
        }
        *depth = this->depth(m_camera > 0.0 ? (double(u0) - m_camera) / (1.0 - m_camera) : double(u0));
        BdptTracer::choose_strategy(*depth, u1, s, t);  // uniform over the strategies
        if (m_camera > 0.0) return strategy_pmf(*depth, *s);
        const double p_st = 1.0 / double(BdptTracer::strategy_count(*depth));
        return depth_pmf(*depth) * p_st;
    }

private:
    std::vector<double> m_cdf;  ///< m_cdf[d] = P(depth < d), m_cdf[max+1] = 1
    int m_min_depth = 0;
    double m_camera = 0.0;                ///< q
    std::vector<float> m_camera_weights;  ///< [2 d + s] = 1 / p_eff(d, s), s ≤ 1
};

}  // namespace cmlt::mlt
