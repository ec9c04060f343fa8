#pragma once
/// \file A render's estimate of its own relMSE, and the rule that stops a frame at a
/// target error (RenderSettings.target_error).
///
/// The estimators are those of src/cmlt/metrics/error_estimate.py (its docstring derives
/// them; tests/python/accuracy/test_target_error.py checks that both sides agree): per
/// pixel and channel e = v / D with v the variance of the pixel's mean and D the guarded
/// trimmed denominator max(R', I / 4)² + ε, ε = 10⁻²: R' the pixel's mean without its
/// largest and its smallest pass, block or chain group (Film::develop's `robust`), which
/// one firefly does not inflate and symmetric noise does not bias, kept from falling
/// below a quarter of the mean I where one pass holds all of the pixel's light; where a
/// pixel has fewer than three passes, blocks or groups (R' NaN: two blocks, the fewest a
/// targeted frame stops after) the geometric denominator sqrt((I² + ε)(max(I² − v, 0) + ε));
/// the image's estimate is the mean of e.
///
/// * passes (pt, bdpt): v is the film's variance of the mean over independent passes,
///   or over independent blocks of passes (Sobol points in blocks, the sampler of a
///   frame with a target error: Film::set_variance_block); the standard error comes
///   from 4 × 4 interleaved sub-images (sd / 4);
/// * chain groups (pssmlt, cmlt): G images Y_g of the same frame from disjoint sets of
///   chains (n_g path evaluations each), v = Σ n_g (Y_g − I)² / ((G − 1) N) plus the parts
///   every group shares — the direct pass's variance and b's, (b_se / b)² C² on the
///   chains' part C; standard error by the delete-one-group jackknife.
///
/// Stopping (ErrorTarget): the frame stops when the estimate E is at most the target T
/// and a one-sided 95 % upper confidence bound U on the expected relMSE is at most
/// 1.5 T (the tolerance, k_target_tolerance), after at least a minimum of work (32
/// passes; 2G chain rounds); the sample and time budgets still bound it. U models E as
/// a scaled chi-square variable, E ~ relMSE · χ²_ν / ν, with the effective degrees of
/// freedom from its standard error (Satterthwaite: ν = 2 (E / se)², matching mean and
/// variance; a few dominant pixels or groups give a small ν, many independent ones a
/// large one): U = E ν / χ²_{0.05}(ν), the chi-square quantile by Wilson–Hilferty.
/// U ≤ 1.5 T is the test of H0 "expected relMSE ≥ 1.5 T" at level α = 5 %: under that
/// model one check stops a frame whose expected error is beyond the tolerance with
/// probability at most 5 % (the false-alarm rate; over the checks of one frame at most
/// 5 % times the checks made while the error is that high — the work grows ≥ 1.1× per
/// check, so few). A frame far below the target stops even when its estimate is rough
/// (a relative standard error rule would keep it running). The next chunk of work is
/// predicted from relMSE ∝ 1 / work: the work at which both E and U / 1.5 would reach
/// 0.95 T, at least 1.1× and at most 2× the work so far, so the frame ends close to the
/// target instead of a budget slice past it.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <vector>

namespace cmlt {

constexpr double k_rel_mse_eps = 1e-2;  ///< ε of relMSE (cmlt.metrics.flicker.REL_MSE_EPS)

struct ErrorValue {
    double relmse = std::numeric_limits<double>::quiet_NaN();
    double stderr_ = std::numeric_limits<double>::quiet_NaN();
    bool valid() const { return std::isfinite(relmse); }
};

/// The share of the mean below which the trimmed mean is not taken (file comment).
constexpr double k_robust_floor = 0.25;

/// e = v / D, the guarded trimmed denominator (file comment): `robust` the pixel's mean
/// without its largest and smallest pass, block or group; NaN: none, the geometric one.
inline double rel_mse_term(double image, double var, double robust) {
    const double v = std::max(var, 0.0);
    if (std::isnan(robust)) {
        const double i2 = image * image;
        return v / std::sqrt((i2 + k_rel_mse_eps) * (std::max(i2 - v, 0.0) + k_rel_mse_eps));
    }
    const double r = std::max(robust, k_robust_floor * image);
    return v / (r * r + k_rel_mse_eps);
}

/// From a (H, W, 3) mean, variance of the mean and trimmed mean (Film::develop's
/// `robust`; null or NaN: none).
inline ErrorValue estimate_from_variance(const float* mean, const float* var, const float* robust, int W, int H) {
    constexpr int k = 4;
    const int kx = std::max(1, std::min(k, W)), ky = std::max(1, std::min(k, H));
    const int kk = std::min(kx, ky);  // the Python side splits k = min(4, H, W) both ways
    std::vector<double> sum(size_t(kk) * kk, 0.0);
    std::vector<uint64_t> count(size_t(kk) * kk, 0);
    double total = 0.0;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const size_t p = size_t(y) * size_t(W) + size_t(x);
            double e = 0.0;
            for (int c = 0; c < 3; ++c) {
                const double m = double(mean[3 * p + c]);
                e += rel_mse_term(m, double(var[3 * p + c]),
                                  robust ? double(robust[3 * p + c]) : std::numeric_limits<double>::quiet_NaN());
            }
            total += e;
            const size_t cell = size_t(y % kk) * kk + size_t(x % kk);
            sum[cell] += e / 3.0;
            count[cell] += 1;
        }
    ErrorValue out;
    const double n = double(W) * double(H);
    out.relmse = total / (3.0 * n);
    if (kk > 1) {
        std::vector<double> sub;
        for (size_t i = 0; i < sum.size(); ++i)
            if (count[i]) sub.push_back(sum[i] / double(count[i]));
        double m = 0.0;
        for (double s : sub) m += s;
        m /= double(sub.size());
        double ss = 0.0;
        for (double s : sub) ss += (s - m) * (s - m);
        out.stderr_ = std::sqrt(ss / double(sub.size() - 1)) / double(kk);
    }
    return out;
}

/// From G group images: `group(g, i)` is group g's value at index i of the (H, W, 3)
/// image (i < n), `weights` its path evaluations; `shared_var(i)` the variance every group
/// shares at i (direct pass, normalisation; see the file comment). `image_out`, if given,
/// receives the weighted mean (the frame's image).
template <class Group, class SharedVar>
ErrorValue estimate_from_groups(size_t n, const std::vector<double>& weights, Group group, SharedVar shared_var,
                                float* image_out = nullptr) {
    ErrorValue out;
    const size_t G = weights.size();
    if (G < 3 || n == 0) return out;
    double N = 0.0;
    for (double w : weights) {
        if (!(w > 0.0)) return out;  // a group without work: no estimate yet
        N += w;
    }
    std::vector<double> y(G), loo(G, 0.0);
    double total = 0.0;
    for (size_t i = 0; i < n; ++i) {
        double s1 = 0.0, s2 = 0.0;
        for (size_t g = 0; g < G; ++g) {
            y[g] = group(g, i);
            s1 += weights[g] * y[g];
            s2 += weights[g] * y[g] * y[g];
        }
        // the two largest and the two smallest groups (strict order, the first of equal
        // values first: cmlt.metrics.error_estimate._extremes)
        size_t top = 0, top2 = 1, bot = 0, bot2 = 1;
        if (y[1] > y[0]) top = 1, top2 = 0;
        if (y[1] < y[0]) bot = 1, bot2 = 0;
        for (size_t g = 2; g < G; ++g) {
            if (y[g] > y[top]) top2 = top, top = g;
            else if (y[g] > y[top2]) top2 = g;
            if (y[g] < y[bot]) bot2 = bot, bot = g;
            else if (y[g] < y[bot2]) bot2 = g;
        }
        const double sv = shared_var(i);
        const double I = s1 / N;
        if (image_out) image_out[i] = float(I);
        const double v = std::max(s2 - N * I * I, 0.0) / (double(G - 1) * N);
        // the trimmed mean (the denominator's R', file comment): without the largest and
        // the smallest group (two different ones: where they would be the same, all the
        // values are equal and the mean is it); NaN with fewer than three groups
        auto trimmed = [&](double s, double n_all, size_t t, size_t b, size_t count) {
            const double rest = n_all - weights[t] - weights[b];
            if (!(count > 2 && rest > 0.0)) return std::numeric_limits<double>::quiet_NaN();
            return t != b ? (s - weights[t] * y[t] - weights[b] * y[b]) / rest : s / n_all;
        };
        total += rel_mse_term(I, v + sv, trimmed(s1, N, top, bot, G));
        for (size_t g = 0; g < G; ++g) {
            const double ng = N - weights[g];
            const double s1g = s1 - weights[g] * y[g], s2g = s2 - weights[g] * y[g] * y[g];
            const double Ig = s1g / ng;
            const double vg = std::max(s2g - ng * Ig * Ig, 0.0) / (double(G - 2) * ng);
            // the largest and smallest of the other groups
            const double rg = trimmed(s1g, ng, g == top ? top2 : top, g == bot ? bot2 : bot, G - 1);
            loo[g] += rel_mse_term(Ig, vg + sv, rg) * (ng / N);
        }
    }
    out.relmse = total / double(n);
    double m = 0.0;
    for (double& l : loo) m += (l /= double(n));
    m /= double(G);
    double ss = 0.0;
    for (double l : loo) ss += (l - m) * (l - m);
    out.stderr_ = std::sqrt(double(G - 1) / double(G) * ss);
    return out;
}

/// Called with each estimate a targeted frame makes, as it makes it (the live estimate):
/// (work done: passes or path evaluations per pixel, seconds into the frame, estimate,
/// its standard error). Runs on the calling thread, between chunks.
using EstimateCallback = std::function<void(double work, double secs, double relmse, double stderr_)>;

/// The listener of the calling thread's render (render() with an EstimateCallback sets
/// it for the call's duration; ErrorTarget::reached calls it).
class ScopedEstimateListener {
public:
    explicit ScopedEstimateListener(const EstimateCallback& cb) : m_prev(slot()) { slot() = cb ? &cb : nullptr; }
    ~ScopedEstimateListener() { slot() = m_prev; }
    ScopedEstimateListener(const ScopedEstimateListener&) = delete;
    ScopedEstimateListener& operator=(const ScopedEstimateListener&) = delete;
    static const EstimateCallback* current() { return slot(); }

private:
    static const EstimateCallback*& slot() {
        thread_local const EstimateCallback* cb = nullptr;
        return cb;
    }
    const EstimateCallback* m_prev;
};

constexpr double k_target_z = 1.6448536269514722;  ///< the standard normal's 95 % quantile
constexpr double k_target_tolerance = 1.5;         ///< U's limit, in targets (file comment)

/// The lower quantile of χ²_ν at the standard normal quantile -z (Wilson–Hilferty: the
/// cube root of χ²_ν / ν is close to normal with mean 1 − 2/(9ν) and variance 2/(9ν));
/// 0 where the approximation leaves the positive axis (ν below ~1).
inline double chi2_lower_quantile(double nu, double z = k_target_z) {
    if (!(nu > 0.0)) return 0.0;
    const double a = 2.0 / (9.0 * nu), c = 1.0 - a - z * std::sqrt(a);
    return c > 0.0 ? nu * c * c * c : 0.0;
}

/// The one-sided 95 % upper confidence bound on the expected relMSE from an estimate and
/// its standard error (the file comment's scaled chi-square model); +inf without a
/// standard error or where the bound is unbounded.
inline double upper_bound(const ErrorValue& e) {
    if (!e.valid() || !std::isfinite(e.stderr_)) return std::numeric_limits<double>::infinity();
    if (e.stderr_ <= 0.0) return e.relmse;
    if (e.relmse <= 0.0) return std::numeric_limits<double>::infinity();
    const double nu = 2.0 * (e.relmse / e.stderr_) * (e.relmse / e.stderr_);
    const double q = chi2_lower_quantile(nu);
    return q > 0.0 ? e.relmse * nu / q : std::numeric_limits<double>::infinity();
}

/// The stopping rule of RenderSettings.target_error and the record of its estimates.
class ErrorTarget {
public:
    ErrorTarget(double target, double min_work) : m_target(target), m_min_work(min_work) {}

    bool enabled() const { return m_target > 0.0; }
    double target() const { return m_target; }

    /// Record the estimate after `work` (passes, or evaluations per pixel) and `secs`;
    /// true when the target is reached.
    bool reached(double work, double secs, const ErrorValue& e) {
        m_last = e;
        m_history.push_back({work, secs, e.relmse, e.stderr_});
        if (const EstimateCallback* cb = ScopedEstimateListener::current()) (*cb)(work, secs, e.relmse, e.stderr_);
        if (!enabled() || !e.valid() || work < m_min_work) return false;
        return e.relmse <= m_target && upper_bound(e) <= k_target_tolerance * m_target;
    }
    /// The work to have done after the next chunk, from `work` done (> 0).
    double min_work() const { return m_min_work; }
    double next_work(double work) const {
        double want = 2.0 * work;
        const double u = upper_bound(m_last);
        if (m_last.valid() && m_last.relmse > 0.0 && std::isfinite(u))
            want = work * std::max(m_last.relmse, u / k_target_tolerance) / (0.95 * m_target);
        want = std::min(std::max(want, 1.1 * work), 2.0 * work);
        return std::max(want, m_min_work);
    }
    const std::vector<std::array<double, 4>>& history() const { return m_history; }
    std::vector<std::array<double, 4>> take_history() { return std::move(m_history); }

private:
    double m_target, m_min_work;
    ErrorValue m_last;
    std::vector<std::array<double, 4>> m_history;
};

/// Passes (pt, bdpt): the chunk to render after `done` passes with a target, given the
/// chunk the budgets allow (`budget_chunk`, PassSchedule::next; `remaining` passes of the
/// sample budget when untimed, which the target's prediction then sizes). `block`: the
/// film's variance block (Film::set_variance_block): the predicted end is rounded up to
/// a whole block, so that every check sees all its passes in the variance.
inline int target_chunk(const ErrorTarget& t, int done, int budget_chunk, bool timed, int remaining,
                        int block = 1) {
    if (!t.enabled() || budget_chunk <= 0) return budget_chunk;
    const int cap = timed ? budget_chunk : remaining;
    const double want = done == 0 ? t.min_work() : t.next_work(double(done));
    int end = int(std::ceil(want));
    if (block > 1) end = (end + block - 1) / block * block;
    return std::max(1, std::min(cap, end - done));
}

/// The stop reason of a frame (RenderResult::stop_reason).
inline std::string stop_reason(bool cancelled, bool target_reached, bool timed, double elapsed, double time_budget) {
    if (cancelled) return "cancelled";
    if (target_reached) return "target";
    if (timed && elapsed >= time_budget) return "time";
    return "budget";
}

/// Passes needed before a pass-based frame may stop at its target: the per-pixel
/// variance of fewer passes misses the rare bright samples of most pixels, and the
/// estimate is low (Cornell box pt, 32x32: estimate × passes 0.28-0.40 after 16 passes,
/// 0.40-0.44 from 128 on, tests/bench/target_error.py).
/// With Sobol points in blocks (the sampler of such a frame: target_min_passes) the
/// estimate is calibrated from 2 blocks on (Cornell box pt, 64x64: estimate / measured
/// 0.96-0.98 from 2 to 16 blocks; README, "Pixel samples").
constexpr double k_target_min_passes = 32.0;

/// The minimum for a film whose variance comes from blocks of `block` passes
/// (Film::variance_block): two blocks, the fewest a spread is taken from; independent
/// passes (block 1): k_target_min_passes.
inline double target_min_passes(uint32_t block) {
    return block > 1 ? 2.0 * double(block) : k_target_min_passes;
}

}  // namespace cmlt
