#pragma once
/// \file What the Metropolis frame loops (pssmlt_integrator.cpp, cmlt_integrator.cpp)
/// share around their chains: the split of the budget, the direct pass, the bootstrap
/// of b, the occupancy statistic of "stuck" chains, and the final image.
///
/// Budget of a frame, spp·W·H path evaluations (a path evaluation is one traced
/// path: a bootstrap sample, a proposal or a candidate, a pilot or direct sample):
///   1. pilot of the pixel importance: pilot_spp·W·H (pixel_importance.h);
///   2. direct pass: round(direct_fraction · spp)·W·H path-traced samples of depth ≤ 1,
///      added to the image as they are (DirectPass); the chains then render depth ≥ 2
///      only. It runs in slices between the chain rounds, so with a time budget it keeps
///      its share of the evaluations whatever the time allows;
///   3. bootstrap: min(bootstrap_samples, half of what is left) large-step samples;
///   4. the chains: the rest, split evenly over the chains.
/// With a time budget the chains run until it is used up (frame_loop.h); 1–3 always run.
#include "cameras/camera.h"
#include "film/film.h"
#include "integrators/common/error_target.h"
#include "integrators/common/frame_loop.h"
#include "integrators/mlt/mlt_context.h"
#include "integrators/mlt/splat_film.h"
#include "integrators/mlt_kernels/normalisation.h"
#include "integrators/path/pt_pass.h"
#include "util/error.h"
#include "util/fp_mode.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <map>
#include <vector>

namespace cmlt::mlt {

struct FrameBudget {
    uint64_t pilot = 0, direct = 0, bootstrap = 0, chains = 0;

    static FrameBudget plan(const RenderSettings& s) {
        FrameBudget b;
        b.pilot = MltContext::pilot_cost(s);
        b.direct = MltContext::direct_cost(s);  // a sample budget's; timed: as it runs
        if (!MltContext::chains_needed(s)) return b;  // max_depth 1 with a direct pass
        const uint64_t left = MltContext::evaluation_budget(s);
        b.bootstrap = std::max<uint64_t>(1, std::min<uint64_t>(uint64_t(s.bootstrap_samples), left / 2));
        b.chains = left - b.bootstrap;
        return b;
    }
};

/// The direct pass (depths 0 and 1) of a Metropolis frame: independent path-traced
/// samples keyed (seed, pixel, k_direct_sample_base + s), accumulated over slices.
class DirectPass {
public:
    DirectPass(const Scene& scene, const RenderSettings& s)
        : m_settings(s), m_camera(scene.camera_desc(), s.width, s.height),
          m_tracer(scene, std::min(1, s.max_depth)), m_motion_blur(scene.motion_blur()),
          m_film(s.width, s.height), m_enabled(s.direct_fraction > 0.0) {}

    bool enabled() const { return m_enabled; }
    int passes() const { return m_passes; }
    uint64_t evaluations() const { return uint64_t(m_passes) * uint64_t(m_settings.width) * uint64_t(m_settings.height); }

    /// Render passes up to `total` (no-op if already there).
    void render_to(tbb::task_arena& arena, int total, FrameCounters& counters) {
        if (!m_enabled || total <= m_passes) return;
        const int s0 = m_passes, s1 = total, W = m_settings.width;
        arena.execute([&] {
            tbb::parallel_for(tbb::blocked_range<int>(0, m_settings.height, 2), [&](const tbb::blocked_range<int>& r) {
                ScopedFtzDaz ftz;
                const TaskTimer timer(counters);
                PathCounters c;
                for (int y = r.begin(); y != r.end(); ++y)
                    for (int x = 0; x < W; ++x)
                        for (int k = s0; k < s1; ++k) {
                            const uint32_t index = k_direct_sample_base + uint32_t(k);
                            m_film.add_sample(x, y, index,
                                              m_tracer.pixel_sample(m_camera, m_motion_blur, m_settings.seed, x, y, W,
                                                                    index, c));
                        }
                counters.add(c);
            });
        });
        m_passes = total;
    }

    /// Passes a time-budgeted frame should have after `chain_evaluations`: the share
    /// direct_fraction of all evaluations (at least one).
    int passes_for(uint64_t chain_evaluations) const {
        const double f = m_settings.direct_fraction;
        const double pixels = double(m_settings.width) * double(m_settings.height);
        return std::max(1, int(std::ceil(f / (1.0 - f) * double(chain_evaluations) / pixels)));
    }

    /// Mean and variance of the mean (H, W, 3); empty without a direct pass.
    PtPassImage develop() const {
        PtPassImage out;
        if (!m_enabled || m_passes == 0) return out;
        const size_t n = size_t(m_settings.width) * size_t(m_settings.height) * 3;
        out.mean.resize(n);
        out.variance.resize(n);
        m_film.develop(out.mean.data(), out.variance.data());
        out.nan_samples = m_film.nan_samples();
        return out;
    }

private:
    const RenderSettings& m_settings;
    Camera m_camera;
    PathTracer m_tracer;
    bool m_motion_blur;
    Film m_film;
    bool m_enabled;
    int m_passes = 0;
};

/// The direct pass's slices around the chain rounds: before round r of a sample budget
/// its share D·(r+1)/k_rounds of the D passes, with a time budget the passes that keep
/// its share of the evaluations so far; `finish` completes a sample budget's D passes
/// (also when the chains were done early or there were none) or, timed and chainless,
/// renders passes until the time is used.
struct DirectSchedule {
    DirectPass& pass;
    const RenderSettings& settings;
    tbb::task_arena& arena;
    FrameCounters& counters;

    void before_round(const ChainSchedule& rounds, uint64_t chain_evaluations) {
        if (!pass.enabled()) return;
        if (rounds.timed()) pass.render_to(arena, pass.passes_for(chain_evaluations), counters);
        else if (rounds.targeted())
            pass.render_to(arena, int(std::ceil(MltContext::direct_spp(settings) * rounds.fraction())), counters);
        else pass.render_to(arena, MltContext::direct_spp(settings) * (rounds.round() + 1) / ChainSchedule::k_rounds,
                            counters);
    }
    void finish(bool cancelled, bool chains_ran, std::chrono::steady_clock::time_point t0) {
        if (!pass.enabled() || cancelled) return;
        if (settings.time_budget <= 0.0) {
            pass.render_to(arena, MltContext::direct_spp(settings), counters);
            return;
        }
        if (chains_ran) return;
        const PassSchedule time(settings, t0);
        while (const int n = time.next(pass.passes())) pass.render_to(arena, pass.passes() + n, counters);
    }
};
/// f* of bootstrap samples 0..n−1, evaluated in parallel by `eval(i, PathCounters&,
/// bool& invalid) -> double`; then b from them in index order (deterministic).
template <class Eval>
std::vector<double> run_bootstrap(tbb::task_arena& arena, uint64_t n, FrameCounters& counters, Eval&& eval) {
    std::vector<double> f(n, 0.0);
    arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n, 256), [&](const tbb::blocked_range<uint64_t>& r) {
            ScopedFtzDaz ftz;
            const TaskTimer timer(counters);
            PathCounters c;
            uint64_t bad = 0;
            for (uint64_t i = r.begin(); i != r.end(); ++i) {
                bool invalid = false;
                f[i] = eval(i, c, invalid);
                bad += invalid ? 1 : 0;
            }
            counters.add(c, bad);
        });
    });
    return f;
}

/// The bootstrap's f*: settings.mlt_bootstrap_f if given (it must hold n values), else
/// run_bootstrap(arena, n, counters, eval).
template <class Eval>
std::vector<double> bootstrap_values(const RenderSettings& s, tbb::task_arena& arena, uint64_t n,
                                     FrameCounters& counters, Eval&& eval) {
    if (!s.mlt_bootstrap_f) return run_bootstrap(arena, n, counters, std::forward<Eval>(eval));
    if (s.mlt_bootstrap_f->size() != n)
        CMLT_THROW(SettingsError, "RenderSettings.mlt_bootstrap_f holds " << s.mlt_bootstrap_f->size()
                                      << " values, the frame's bootstrap has " << n << " samples");
    return *s.mlt_bootstrap_f;
}

/// How long chains sit in one state. A state is occupied for 1 + (rejections that
/// follow) steps; `top_fraction(q)` is the share of all steps spent in the most-occupied
/// fraction q of the states visited (issue 4's "no chain sticks" measure: with q = 0.1 %
/// a healthy chain population gives a few percent, a stuck one most of its steps).
class Occupancy {
public:
    void add_run(uint64_t steps) {
        if (steps == 0) return;
        if (steps < k_dense) ++m_dense[steps];
        else ++m_sparse[steps];
        m_total += steps;
        ++m_states;
    }
    void merge(const Occupancy& o) {
        for (size_t i = 0; i < k_dense; ++i) m_dense[i] += o.m_dense[i];
        for (const auto& kv : o.m_sparse) m_sparse[kv.first] += kv.second;
        m_total += o.m_total;
        m_states += o.m_states;
    }
    uint64_t states() const { return m_states; }
    uint64_t steps() const { return m_total; }
    double top_fraction(double q) const {
        if (m_total == 0) return 0.0;
        uint64_t take = uint64_t(std::ceil(q * double(m_states)));
        uint64_t sum = 0;
        for (auto it = m_sparse.rbegin(); it != m_sparse.rend() && take > 0; ++it) {
            const uint64_t k = std::min(take, it->second);
            sum += k * it->first;
            take -= k;
        }
        for (size_t len = k_dense; len-- > 1 && take > 0;) {
            const uint64_t k = std::min(take, m_dense[len]);
            sum += k * len;
            take -= k;
        }
        return double(sum) / double(m_total);
    }

private:
    static constexpr size_t k_dense = 256;
    uint64_t m_dense[k_dense] = {};
    std::map<uint64_t, uint64_t> m_sparse;
    uint64_t m_total = 0, m_states = 0;
};

/// Rejection runs and occupancy of one chain.
struct StreakTracker {
    static constexpr uint64_t k_long_streak = 1000;  ///< "stuck" rejection run (stats)
    uint64_t streak = 0, max_streak = 0, long_streak_rejections = 0;
    Occupancy occupancy;

    void record(bool moved) {
        if (moved) {
            end();
        } else {
            max_streak = std::max(max_streak, ++streak);
        }
    }
    void merge(const StreakTracker& o) {
        max_streak = std::max(max_streak, o.max_streak);
        long_streak_rejections += o.long_streak_rejections;
        occupancy.merge(o.occupancy);
    }
    /// The current state's run ends (a move, or the end of the frame).
    void end() {
        if (streak > k_long_streak) long_streak_rejections += streak;
        occupancy.add_run(streak + 1);
        streak = 0;
    }
};

/// The frame's image: b·W·H/steps times the splat sums, plus the direct pass; the
/// variance AOV is the direct pass's (correlated chain samples have none per pixel).
inline void develop_image(RenderResult& res, const SplatFilm& film, double b, uint64_t steps,
                          const PtPassImage& direct) {
    const size_t pixels = size_t(res.width) * size_t(res.height);
    res.image.assign(pixels * 3, 0.f);
    res.variance.assign(pixels * 3, 0.f);
    const double scale = steps > 0 ? b * double(pixels) / double(steps) : 0.0;
    for (size_t i = 0; i < pixels; ++i)
        for (int k = 0; k < 3; ++k) {
            const double chain = scale * film.sum(i, k);
            const double d = direct.mean.empty() ? 0.0 : double(direct.mean[3 * i + k]);
            res.image[3 * i + k] = float(chain + d);
        }
    if (!direct.mean.empty()) {
        res.direct = direct.mean;
        res.variance = direct.variance;
    }
}

/// Layers of the frame's splat film: the error groups (RenderSettings.error_groups; chain
/// c splats into layer c mod G), or 1 without an estimate.
inline int error_layers(const RenderSettings& s) { return s.error_groups >= 3 ? s.error_groups : 1; }

/// The relMSE estimate of a Metropolis frame from its film's layers (error_target.h):
/// group g's image is b·W·H/steps[g] times its layer plus the direct pass; every group
/// shares the direct pass's variance and b's, (b_se/b)² on the chains' part. Optionally
/// writes the group images (G, H, W, 3). No estimate without >= 3 layers.
inline ErrorValue estimate_groups(const SplatFilm& film, const std::vector<double>& steps,
                                  const NormalisationEstimate& b, const PtPassImage& direct,
                                  std::vector<float>* group_images = nullptr) {
    const int G = film.layers();
    if (G < 3 || int(steps.size()) != G || !(b.mean > 0.0)) return ErrorValue{};
    const size_t pixels = size_t(film.width()) * size_t(film.height()), n = pixels * 3;
    double total = 0.0;
    std::vector<double> scale(static_cast<size_t>(G));
    for (int g = 0; g < G; ++g) {
        total += steps[size_t(g)];
        scale[size_t(g)] = steps[size_t(g)] > 0.0 ? b.mean * double(pixels) / steps[size_t(g)] : 0.0;
    }
    if (total <= 0.0) return ErrorValue{};
    const double s_all = b.mean * double(pixels) / total;
    const double b_rel_var = b.std_error > 0.0 ? (b.std_error / b.mean) * (b.std_error / b.mean) : 0.0;
    const bool has_direct = !direct.mean.empty();
    auto group = [&](size_t g, size_t i) {
        return scale[g] * film.layer_sum(int(g), i / 3, int(i % 3)) + (has_direct ? double(direct.mean[i]) : 0.0);
    };
    auto shared = [&](size_t i) {
        const double c = s_all * film.sum(i / 3, int(i % 3));
        return (has_direct ? double(direct.variance[i]) : 0.0) + b_rel_var * c * c;
    };
    if (group_images) {
        group_images->resize(size_t(G) * n);
        for (size_t g = 0; g < size_t(G); ++g)
            for (size_t i = 0; i < n; ++i) (*group_images)[g * n + i] = float(group(g, i));
    }
    return estimate_from_groups(n, steps, group, shared);
}

/// Image normalisation counts per error group: `count(chain)` of chain c added to
/// group c mod G.
template <class Chains, class Count>
std::vector<double> group_counts(const Chains& chains, int G, Count count) {
    std::vector<double> out(size_t(std::max(G, 1)), 0.0);
    for (size_t c = 0; c < chains.size(); ++c) out[c % out.size()] += double(count(*chains[c]));
    return out;
}

/// b so far: the bootstrap and every chain's large steps (chain order).
template <class Chains>
NormalisationEstimate b_so_far(const NormalisationAccumulator& boot, const Chains& chains) {
    NormalisationAccumulator acc = boot;
    for (const auto& st : chains) acc.merge(st->large);
    return acc.estimate();
}

/// After a chain round of a frame with a target error: the estimate, recorded in `t`;
/// true when the target is reached (not before round 2G, the first 2G rounds being equal
/// slices: the chains must have moved before their groups' spread means much), else the
/// schedule's
/// next share of the chains' budget (`evaluations` of `chain_budget` spent so far).
/// `work`: path evaluations per pixel so far (the history's unit).
inline bool target_round(ErrorTarget& t, ChainSchedule& schedule, const ErrorValue& e, double work,
                         uint64_t evaluations, uint64_t chain_budget, int groups) {
    const int done = schedule.round() + 1;  // rounds run
    const bool reached = t.reached(work, schedule.elapsed(), e) && done >= 2 * groups;
    if (reached || chain_budget == 0) return reached;
    const double f = double(evaluations) / double(chain_budget);
    // the first 2G rounds grow linearly (equal slices), then as the target predicts
    schedule.set_fraction(done < 2 * groups ? f * double(done + 1) / double(done) : t.next_work(f));
    return false;
}

/// The first share of the chains' budget a targeted frame runs (and each of its first 2G
/// rounds): 2 evaluations per pixel (a chain whose share is less than one block of
/// `block` evaluations runs a block in the rounds where its share passes one).
inline double target_first_fraction(uint64_t pixels, uint64_t chains, uint64_t block, uint64_t chain_budget) {
    (void)chains;
    (void)block;
    if (chain_budget == 0) return 1.0;
    return std::min(1.0, double(2 * pixels) / double(chain_budget));
}

/// MltStats fields both Metropolis integrators fill the same way.
inline void fill_common_mlt_stats(MltStats& m, const RenderSettings& s, const FrameBudget& budget,
                                  const NormalisationEstimate& b, const NormalisationEstimate& b_boot,
                                  const StreakTracker& streaks, uint64_t direct_evaluations) {
    m.enabled = true;
    m.b = b.mean;
    m.b_stderr = b.std_error;
    m.b_bootstrap = b_boot.mean;
    m.b_bootstrap_stderr = b_boot.std_error;
    m.bootstrap_samples = budget.bootstrap;
    m.bootstrap_nonzero = b_boot.nonzero;
    m.sigma = s.sigma;
    m.max_rejection_streak = streaks.max_streak;
    m.long_streak_rejections = streaks.long_streak_rejections;
    m.states_visited = streaks.occupancy.states();
    m.top_occupancy = streaks.occupancy.top_fraction(0.001);
    m.path_sampler = s.mlt_path_sampler;
    m.importance = s.importance;
    m.pilot_evaluations = budget.pilot;
    m.direct_evaluations = direct_evaluations;
    m.min_depth = MltContext::min_depth(s);
    m.time_budget = s.time_budget;
}

}  // namespace cmlt::mlt
