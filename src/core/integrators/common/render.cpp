#include "integrators/common/render.h"

#include "cameras/camera.h"
#include "film/film.h"
#include "integrators/bdpt/bdpt_integrator.h"
#include "integrators/cmlt/cmlt_integrator.h"
#include "integrators/common/error_target.h"
#include "integrators/common/frame_loop.h"
#include "integrators/mlt/pssmlt_integrator.h"
#include "integrators/path/path_tracer.h"
#include "sampling/rng.h"
#include "util/error.h"
#include "util/fp_mode.h"

#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>

namespace cmlt {

namespace {

constexpr int k_tile_size = 16;

struct Tile {
    int x0, y0, x1, y1;
};

}  // namespace

RenderResult render(Scene& scene, const RenderSettings& settings, const ProgressCallback& progress) {
    settings.validate();
    if (!scene.has_camera()) throw SceneError("render: the scene has no camera (call set_camera)");
    if (scene.dirty()) scene.commit();
    if (settings.integrator == "bdpt") return render_bdpt(scene, settings, progress);
    if (settings.integrator == "pssmlt") return render_pssmlt(scene, settings, progress);
    if (settings.integrator == "cmlt") return render_cmlt(scene, settings, progress);

    const int W = settings.width, H = settings.height;
    Camera camera(scene.camera_desc(), W, H);
    Film film(W, H);
    PathTracer tracer(scene, settings.max_depth);
    const bool motion_blur = scene.motion_blur();  // draw a shutter time per sample?

    std::vector<Tile> tiles;
    for (int y = 0; y < H; y += k_tile_size)
        for (int x = 0; x < W; x += k_tile_size)
            tiles.push_back({x, y, std::min(x + k_tile_size, W), std::min(y + k_tile_size, H)});

    int threads = settings.threads > 0 ? settings.threads : tbb::info::default_concurrency();
    tbb::task_arena arena(threads);

    // Chunks of samples per pixel: about 16 progress calls per frame (frame_loop.h).
    FrameCounters counters;
    const CycleRate rate;
    const auto t0 = std::chrono::steady_clock::now();
    const PassSchedule schedule(settings, t0);
    bool cancelled = false;
    int done = 0;
    ErrorTarget target(settings.target_error, k_target_min_passes);
    std::vector<float> est_mean, est_var;  // the film developed for the target's estimates
    bool target_reached = false;
    while (const int n = target_chunk(target, done, schedule.next(done), schedule.timed(), settings.spp - done)) {
        const int s0 = done, s1 = done + n;
        arena.execute([&] {
            tbb::parallel_for(
                tbb::blocked_range<size_t>(0, tiles.size(), 1),
                [&](const tbb::blocked_range<size_t>& r) {
                    ScopedFtzDaz ftz;
                    const TaskTimer timer(counters);
                    PathCounters c;
                    for (size_t ti = r.begin(); ti != r.end(); ++ti) {
                        const Tile& tile = tiles[ti];
                        for (int y = tile.y0; y < tile.y1; ++y)
                            for (int x = tile.x0; x < tile.x1; ++x)
                                for (int s = s0; s < s1; ++s) {
                                    const Spectrum L = tracer.pixel_sample(camera, motion_blur, settings.seed,
                                                                           x, y, W, uint32_t(s), c);
                                    film.add_sample(x, y, uint32_t(s), L);
                                }
                    }
                    counters.add(c);
                },
                tbb::simple_partitioner());
        });
        done = s1;
        if (target.enabled()) {
            est_mean.resize(size_t(W) * H * 3);
            est_var.resize(size_t(W) * H * 3);
            film.develop(est_mean.data(), est_var.data());
            if (target.reached(double(done), schedule.elapsed(),
                               estimate_from_variance(est_mean.data(), est_var.data(), W, H))) {
                target_reached = true;
                break;
            }
        }
        if (progress && !progress(schedule.progress_done(done), schedule.progress_total()) &&
            schedule.next(done) > 0) {
            cancelled = true;
            break;
        }
    }
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    RenderResult res;
    res.width = W;
    res.height = H;
    res.image.resize(size_t(W) * H * 3);
    res.variance.resize(size_t(W) * H * 3);
    film.develop(res.image.data(), res.variance.data());
    res.cancelled = cancelled;
    const ErrorValue err = estimate_from_variance(res.image.data(), res.variance.data(), W, H);
    res.error_estimate = err.relmse;
    res.error_stderr = err.stderr_;
    res.error_history = target.take_history();
    res.stop_reason = stop_reason(cancelled, target_reached, schedule.timed(), secs, settings.time_budget);
    RenderStats& st = res.stats;
    fill_frame_stats(st, counters, rate, secs);
    st.nan_samples = film.nan_samples();
    int fx, fy;
    uint32_t fs;
    if (film.first_nan(&fx, &fy, &fs)) {
        st.first_nan_x = fx;
        st.first_nan_y = fy;
        st.first_nan_sample = fs;
    }
    st.threads = threads;
    st.integrator = settings.integrator;
    st.spp = done;
    st.seed = settings.seed;
    return res;
}

}  // namespace cmlt
