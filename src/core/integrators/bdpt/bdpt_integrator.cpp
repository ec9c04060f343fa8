#include "integrators/bdpt/bdpt_integrator.h"

#include "cameras/camera.h"
#include "film/film.h"
#include "integrators/bdpt/bdpt_tracer.h"
#include "integrators/common/error_target.h"
#include "integrators/common/frame_loop.h"
#include "scene/scene.h"
#include "util/fp_mode.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>

namespace cmlt {

namespace {

constexpr int k_tile_size = 16;

struct Tile {
    int x0, y0, x1, y1;
};

}  // namespace

RenderResult render_bdpt(const Scene& scene, const RenderSettings& settings,
                         const ProgressCallback& progress) {
    const int W = settings.width, H = settings.height;
    Camera camera(scene.camera_desc(), W, H);
    Film film(W, H);
    BdptTracer tracer(scene, camera, W, H, settings.max_depth);

    std::vector<Tile> tiles;
    for (int y = 0; y < H; y += k_tile_size)
        for (int x = 0; x < W; x += k_tile_size)
            tiles.push_back({x, y, std::min(x + k_tile_size, W), std::min(y + k_tile_size, H)});

    int threads = settings.threads > 0 ? settings.threads : tbb::info::default_concurrency();
    tbb::task_arena arena(threads);

    const size_t n_pix = size_t(W) * size_t(H);
    std::vector<Spectrum> pass_L(n_pix);
    std::vector<double> splat_img(3 * n_pix);
    std::vector<std::vector<BdptSplat>> tile_splats(tiles.size());
    tbb::enumerable_thread_specific<BdptWorkspace> workspaces;

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
        const int s1 = done + n;
        for (int pass = done; pass < s1; ++pass) {
            // Trace: one sample per pixel, splats kept per tile.
            arena.execute([&] {
                tbb::parallel_for(
                    tbb::blocked_range<size_t>(0, tiles.size(), 1),
                    [&](const tbb::blocked_range<size_t>& r) {
                        ScopedFtzDaz ftz;
                        const TaskTimer timer(counters);
                        BdptWorkspace& ws = workspaces.local();
                        BdptCounters c;
                        for (size_t ti = r.begin(); ti != r.end(); ++ti) {
                            const Tile& tile = tiles[ti];
                            std::vector<BdptSplat>& out = tile_splats[ti];
                            out.clear();
                            for (int y = tile.y0; y < tile.y1; ++y)
                                for (int x = tile.x0; x < tile.x1; ++x) {
                                    uint32_t pixel = uint32_t(y) * uint32_t(W) + uint32_t(x);
                                    PixelStreamSampler sampler(settings.seed, pixel, uint32_t(pass));
                                    sampler.start_stream(BdptSampler::k_camera);
                                    Vec2 u = sampler.next2d();
                                    ws.splats.clear();
                                    pass_L[pixel] = tracer.li(Vec2(float(x) + u.x, float(y) + u.y),
                                                              sampler, ws, c);
                                    for (const BdptSplat& sp : ws.splats) {
                                        if (!is_finite(sp.L)) {
                                            c.bad_splats += 1;
                                            continue;
                                        }
                                        out.push_back(sp);
                                    }
                                }
                        }
                        counters.add(c);
                        counters.splats.fetch_add(c.splats, std::memory_order_relaxed);
                        counters.bad_splats.fetch_add(c.bad_splats, std::memory_order_relaxed);
                    },
                    tbb::simple_partitioner());
            });
            // Merge the splats in tile order (deterministic sums).
            std::fill(splat_img.begin(), splat_img.end(), 0.0);
            for (const auto& list : tile_splats)
                for (const BdptSplat& sp : list) {
                    int px = std::min(W - 1, std::max(0, int(std::floor(sp.p_raster.x))));
                    int py = std::min(H - 1, std::max(0, int(std::floor(sp.p_raster.y))));
                    double* d = &splat_img[3 * (size_t(py) * size_t(W) + size_t(px))];
                    d[0] += double(sp.L.x);
                    d[1] += double(sp.L.y);
                    d[2] += double(sp.L.z);
                }
            // One film sample per pixel: pass estimate + its splats.
            arena.execute([&] {
                tbb::parallel_for(tbb::blocked_range<int>(0, H), [&](const tbb::blocked_range<int>& r) {
                    for (int y = r.begin(); y != r.end(); ++y)
                        for (int x = 0; x < W; ++x) {
                            size_t i = size_t(y) * size_t(W) + size_t(x);
                            const double* d = &splat_img[3 * i];
                            Spectrum v(float(double(pass_L[i].x) + d[0]),
                                       float(double(pass_L[i].y) + d[1]),
                                       float(double(pass_L[i].z) + d[2]));
                            film.add_sample(x, y, uint32_t(pass), v);
                        }
                });
            });
        }
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
    res.image.resize(n_pix * 3);
    res.variance.resize(n_pix * 3);
    film.develop(res.image.data(), res.variance.data());
    res.cancelled = cancelled;
    const ErrorValue err = estimate_from_variance(res.image.data(), res.variance.data(), W, H);
    res.error_estimate = err.relmse;
    res.error_stderr = err.stderr_;
    res.error_history = target.take_history();
    res.stop_reason = stop_reason(cancelled, target_reached, schedule.timed(), secs, settings.time_budget);
    RenderStats& st = res.stats;
    fill_frame_stats(st, counters, rate, secs);
    st.splats = counters.splats.load();
    st.nan_samples = film.nan_samples() + counters.bad_splats.load();
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
