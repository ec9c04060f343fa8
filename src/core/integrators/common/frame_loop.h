#pragma once
/// \file Pieces every integrator's frame loop shares: the thread arena and its parallel
/// tasks, counters summed over the tasks, the trace / shade time split, image tiles, and
/// the schedule of passes (pt, bdpt) or chain rounds (pssmlt, cmlt) under a sample
/// budget and an optional time budget.
///
/// Budgets. `spp` is the budget of samples (pt, bdpt) or path evaluations per pixel
/// (pssmlt, cmlt). With `time_budget` > 0 seconds the frame also stops when that much
/// wall time has passed since the frame started — whichever comes first; work is
/// scheduled in chunks sized from the measured speed so a frame ends within about a
/// sixteenth of its budget of the mark (and at least one chunk always runs). A timed
/// frame depends on the machine's speed, so it is not reproducible bit for bit; a
/// sample-budget frame is.
#include "accel/accel.h"
#include "film/film.h"
#include "integrators/common/error_target.h"
#include "integrators/common/path_counters.h"
#include "integrators/common/render_settings.h"
#include "util/cycle_clock.h"
#include "util/fp_mode.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <vector>

namespace cmlt {

class Film;

/// Counters of one frame summed over its tasks (integer sums: order-independent).
struct FrameCounters {
    std::atomic<uint64_t> camera_rays{0}, shadow_rays{0}, rays{0}, samples{0};
    std::atomic<uint64_t> invalid{0}, packets{0}, splats{0}, bad_splats{0};
    std::atomic<uint64_t> busy_ticks{0}, trace_ticks{0};
    std::atomic<uint64_t> lane_hits{0};  ///< pt: hits shaded in the diffuse lanes (PathBatch)

    /// Ray counts of PathCounters or BdptCounters.
    template <class C>
    void add(const C& c, uint64_t invalid_samples = 0, uint64_t packet_queries = 0) {
        camera_rays.fetch_add(c.camera_rays, std::memory_order_relaxed);
        shadow_rays.fetch_add(c.shadow_rays, std::memory_order_relaxed);
        rays.fetch_add(c.rays, std::memory_order_relaxed);
        samples.fetch_add(c.samples, std::memory_order_relaxed);
        invalid.fetch_add(invalid_samples, std::memory_order_relaxed);
        packets.fetch_add(packet_queries, std::memory_order_relaxed);
    }
    /// The rays and samples counted so far.
    PathCounters paths() const {
        PathCounters c;
        c.camera_rays = camera_rays.load();
        c.shadow_rays = shadow_rays.load();
        c.rays = rays.load();
        c.samples = samples.load();
        return c;
    }
};

/// RAII over one parallel task body: adds the task's wall ticks (busy time) and the
/// ticks its thread spent in BVH queries (Accel::take_trace_ticks) to the counters.
class TaskTimer {
public:
    explicit TaskTimer(FrameCounters& c) : m_c(c), m_t0(cycle_now()) { Accel::take_trace_ticks(); }
    ~TaskTimer() {
        m_c.busy_ticks.fetch_add(cycle_now() - m_t0, std::memory_order_relaxed);
        m_c.trace_ticks.fetch_add(Accel::take_trace_ticks(), std::memory_order_relaxed);
    }
    TaskTimer(const TaskTimer&) = delete;
    TaskTimer& operator=(const TaskTimer&) = delete;

private:
    FrameCounters& m_c;
    uint64_t m_t0;
};

/// The counters' common stats (rays, samples, time split) into `st`.
inline void fill_frame_stats(RenderStats& st, const FrameCounters& c, const CycleRate& rate, double secs) {
    st.time_s = secs;
    st.samples = c.samples.load();
    st.camera_rays = c.camera_rays.load();
    st.shadow_rays = c.shadow_rays.load();
    st.rays = c.rays.load();
    st.rays_per_s = secs > 0 ? double(st.rays) / secs : 0.0;
    st.packets = c.packets.load();
    st.lane_hits = c.lane_hits.load();
    const double per_s = rate.per_second();
    st.busy_s = double(c.busy_ticks.load()) / per_s;
    st.trace_s = std::min(st.busy_s, double(c.trace_ticks.load()) / per_s);
    st.shade_s = st.busy_s - st.trace_s;
}

/// Seconds since `t0`.
inline double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Worker threads of a frame: the setting, or every core for 0.
int frame_threads(const RenderSettings& s);

/// Run `body(const tbb::blocked_range<Index>&)` over [0, n) in the arena, in tasks of
/// `grain` items. Every task runs with FTZ/DAZ set (util/fp_mode.h: the same arithmetic
/// on every thread) and adds its time to `counters` (TaskTimer). The partitioner is
/// tbb's default unless given (tbb::simple_partitioner for one tile per task).
template <class Index, class Body, class Partitioner = const tbb::auto_partitioner>
void parallel_tasks(tbb::task_arena& arena, FrameCounters& counters, Index n, Index grain, Body&& body,
                    Partitioner&& partitioner = Partitioner()) {
    arena.execute([&] {
        tbb::parallel_for(
            tbb::blocked_range<Index>(Index(0), n, grain),
            [&](const tbb::blocked_range<Index>& r) {
                ScopedFtzDaz ftz;
                const TaskTimer timer(counters);
                body(r);
            },
            partitioner);
    });
}

/// A rectangle of pixels [x0, x1) × [y0, y1): the unit of work of the pass integrators.
struct Tile {
    int x0, y0, x1, y1;
};
inline constexpr int k_tile_size = 16;
/// The image in tiles of k_tile_size², row by row.
std::vector<Tile> image_tiles(int width, int height);

/// The budgets of a frame as both schedules see them: `spp` and an optional time budget
/// counted from the frame's start; progress is reported in `spp` units, or in
/// milliseconds of the time budget when there is one.
class FrameBudgetClock {
public:
    FrameBudgetClock(const RenderSettings& s, std::chrono::steady_clock::time_point start)
        : m_spp(s.spp), m_seconds(s.time_budget), m_start(start) {}

    bool timed() const { return m_seconds > 0.0; }
    double elapsed() const { return seconds_since(m_start); }
    /// Progress (done, total) for the callback: `done` in spp units, or the milliseconds
    /// elapsed of the time budget.
    uint64_t progress_done(uint64_t done) const {
        return timed() ? uint64_t(std::min(elapsed(), m_seconds) * 1000.0) : done;
    }
    uint64_t progress_total() const { return timed() ? uint64_t(m_seconds * 1000.0) : uint64_t(m_spp); }
    int spp() const { return m_spp; }

protected:
    int m_spp;
    double m_seconds;
    std::chrono::steady_clock::time_point m_start;
};

/// Passes (pt, bdpt): how many sample passes to run next.
class PassSchedule : public FrameBudgetClock {
public:
    PassSchedule(const RenderSettings& s, std::chrono::steady_clock::time_point start)
        : FrameBudgetClock(s, start), m_chunk(std::max(1, (s.spp + 15) / 16)) {}

    /// Passes to run after `done` of them (0: stop).
    int next(int done) const {
        if (done >= m_spp) return 0;
        if (!timed()) return std::min(m_chunk, m_spp - done);
        const double t = elapsed();
        if (done > 0 && t >= m_seconds) return 0;
        if (done == 0) return 1;
        const double per_pass = t / double(done);
        const double slice = std::min(m_seconds - t, m_seconds / 16.0);
        const double n = std::floor(slice / std::max(per_pass, 1e-9));
        return int(std::max(1.0, std::min(n, double(m_spp - done))));
    }
    /// Progress as (done, total) for the callback: passes, or milliseconds when timed.
    uint64_t progress_done(int done) const { return FrameBudgetClock::progress_done(uint64_t(done)); }

private:
    int m_chunk;
};

/// A pass frame's target error (RenderSettings.target_error, error_target.h): the film
/// its estimates come from, and whether it was reached.
struct PassTarget {
    PassTarget(const RenderSettings& s, const Film& f)
        : target(s.target_error, target_min_passes(f.variance_block())), film(f) {}
    ErrorTarget target;
    const Film& film;
    bool reached = false;
    /// After `done` passes, `secs` into the frame: the estimate, recorded; true when
    /// the target is reached (then `reached` is set).
    bool check(int done, double secs);
};

/// The pass loop of pt and bdpt: `run(s0, s1)` renders passes [s0, s1) in chunks the
/// schedule sizes (with a `target`, chunks it predicts, within the budgets; the frame
/// stops when it is reached); after each chunk `progress` may stop the frame
/// (*cancelled is set unless that chunk was the last). Returns the passes rendered.
template <class Run>
int run_passes(const PassSchedule& schedule, const ProgressCallback& progress, bool* cancelled, Run&& run,
               PassTarget* target = nullptr) {
    const bool targeted = target && target->target.enabled();
    int done = 0;
    while (const int n = targeted ? target_chunk(target->target, done, schedule.next(done), schedule.timed(),
                                                 schedule.spp() - done, int(target->film.variance_block()))
                                  : schedule.next(done)) {
        run(done, done + n);
        done += n;
        if (targeted && target->check(done, schedule.elapsed())) break;
        if (progress && !progress(schedule.progress_done(done), schedule.progress_total()) &&
            schedule.next(done) > 0) {
            *cancelled = true;
            break;
        }
    }
    return done;
}

/// The result of a pass integrator: the film's mean and variance of the mean, its
/// non-finite samples, the counters' stats, and the frame's settings.
/// Also the film's relMSE estimate (error_target.h), the target's history and the stop
/// reason.
RenderResult film_result(const Film& film, const FrameCounters& counters, const CycleRate& rate, double secs,
                         const RenderSettings& settings, int threads, int passes, bool cancelled,
                         PassTarget* target = nullptr);

/// Chain rounds (pssmlt, cmlt): the evaluation count each chain runs to in this round.
/// Fixed budget: k_rounds slices of each chain's budget. Timed: a quota per chain per
/// round, sized from the measured evaluation rate, until the time is up (or every
/// chain has spent its budget).
class ChainSchedule : public FrameBudgetClock {
public:
    static constexpr int k_rounds = 16;  ///< progress / cancel granularity of a fixed budget

    ChainSchedule(const RenderSettings& s, std::chrono::steady_clock::time_point frame_start, uint64_t chains)
        : FrameBudgetClock(s, frame_start), m_chains(std::max<uint64_t>(chains, 1)), m_target(s.target_error > 0.0) {}

    /// With a target error (error_target.h): rounds end at a share `f` of each chain's
    /// budget set before each round (and within the time budget's quota, if timed)
    /// instead of the k_rounds slices.
    bool targeted() const { return m_target; }
    void set_fraction(double f) { m_fraction = std::min(1.0, std::max(f, 0.0)); }
    double fraction() const { return m_fraction; }

    /// Begin the next round; false when the frame is done. `evaluations_so_far`: every
    /// chain's evaluations summed (for the rate).
    bool begin_round(uint64_t evaluations_so_far) {
        if (!timed()) return m_target || m_round < k_rounds;  // targeted: until the budget is spent
        const double t = elapsed();
        if (m_round > 0 && t >= m_seconds) return false;
        if (m_round == 0) {
            m_rate_t0 = t;
            m_quota = 16;
        } else {
            const double dt = t - m_rate_t0;
            const double rate = dt > 0 ? double(evaluations_so_far) / dt : 0.0;  // evaluations / s
            const double slice = std::min(m_seconds - t, m_seconds / 16.0);
            const double q = rate * slice / double(m_chains);
            m_quota = uint64_t(std::max(1.0, std::min(q, 1e12)));
        }
        return true;
    }
    /// Evaluation count chain with `budget` and `done` evaluations runs to this round.
    uint64_t round_end(uint64_t budget, uint64_t done) const {
        if (m_target) {
            const uint64_t want = std::min(budget, uint64_t(std::ceil(double(budget) * m_fraction)));
            return timed() ? std::min(want, done + m_quota) : want;
        }
        if (!timed()) return budget * uint64_t(m_round + 1) / k_rounds;
        return std::min(budget, done + m_quota);
    }
    /// After a round: advance the round counter, set *evaluations to every chain's
    /// evaluations (`done(chain)`, chains with a `budget`), report progress. False when
    /// the frame ends: every chain has spent its budget, or `progress` asked to stop
    /// before the last round (then *cancelled is set).
    template <class Chains, class Done>
    bool end_round(const Chains& chains, Done done, const ProgressCallback& progress,
                   uint64_t* evaluations, bool* cancelled) {
        ++m_round;
        *evaluations = 0;
        bool all_done = true;
        for (const auto& st : chains) {
            const uint64_t d = done(*st);
            *evaluations += d;
            all_done = all_done && d >= st->budget;
        }
        if (all_done) return false;
        if (progress && !progress(progress_done(), progress_total()) && !last_round()) {
            *cancelled = true;
            return false;
        }
        return true;
    }
    int round() const { return m_round; }
    bool last_round() const { return !timed() && !m_target && m_round >= k_rounds; }

    uint64_t progress_done() const {
        return FrameBudgetClock::progress_done(m_target ? uint64_t(double(m_spp) * m_fraction)
                                                        : uint64_t(m_spp) * uint64_t(m_round) / k_rounds);
    }

private:
    uint64_t m_chains;
    int m_round = 0;
    double m_rate_t0 = 0.0;
    uint64_t m_quota = 16;
    bool m_target = false;
    double m_fraction = 1.0;
};

}  // namespace cmlt
