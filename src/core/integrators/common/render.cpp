#include "integrators/common/render.h"

#include "cameras/camera.h"
#include "film/film.h"
#include "integrators/bdpt/bdpt_integrator.h"
#include "integrators/cmlt/cmlt_integrator.h"
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

    // Chunks of samples per pixel: at most ~16 progress calls per frame.
    const int spp = settings.spp;
    const int chunk = std::max(1, (spp + 15) / 16);

    std::atomic<uint64_t> camera_rays{0}, shadow_rays{0}, rays{0}, samples{0};
    auto t0 = std::chrono::steady_clock::now();
    bool cancelled = false;
    int done = 0;
    while (done < spp) {
        const int s0 = done, s1 = std::min(spp, done + chunk);
        arena.execute([&] {
            tbb::parallel_for(
                tbb::blocked_range<size_t>(0, tiles.size(), 1),
                [&](const tbb::blocked_range<size_t>& r) {
                    ScopedFtzDaz ftz;
                    PathCounters c;
                    for (size_t ti = r.begin(); ti != r.end(); ++ti) {
                        const Tile& tile = tiles[ti];
                        for (int y = tile.y0; y < tile.y1; ++y)
                            for (int x = tile.x0; x < tile.x1; ++x) {
                                uint32_t pixel = uint32_t(y) * uint32_t(W) + uint32_t(x);
                                for (int s = s0; s < s1; ++s) {
                                    PixelSampler sampler(settings.seed, pixel, uint32_t(s));
                                    Vec2 u = sampler.get2d();
                                    Ray ray = camera.generate_ray(Vec2(float(x) + u.x, float(y) + u.y));
                                    if (camera.has_lens()) {  // thin lens: its own dimension
                                        PixelSampler ls(settings.seed, pixel, uint32_t(s));
                                        ls.set_dimension(k_lens_dimension);
                                        ray = camera.generate_ray(
                                            Vec2(float(x) + u.x, float(y) + u.y), ls.get2d());
                                    }
                                    if (motion_blur) {
                                        PixelSampler ts(settings.seed, pixel, uint32_t(s));
                                        ts.set_dimension(k_shutter_time_dimension);
                                        ray.time = ts.get1d();
                                    }
                                    Spectrum L = tracer.li(ray, sampler, c);
                                    film.add_sample(x, y, uint32_t(s), L);
                                }
                            }
                    }
                    camera_rays.fetch_add(c.camera_rays, std::memory_order_relaxed);
                    shadow_rays.fetch_add(c.shadow_rays, std::memory_order_relaxed);
                    rays.fetch_add(c.rays, std::memory_order_relaxed);
                    samples.fetch_add(c.samples, std::memory_order_relaxed);
                },
                tbb::simple_partitioner());
        });
        done = s1;
        if (progress && !progress(uint64_t(done), uint64_t(spp)) && done < spp) {
            cancelled = true;
            break;
        }
    }
    double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    RenderResult res;
    res.width = W;
    res.height = H;
    res.image.resize(size_t(W) * H * 3);
    res.variance.resize(size_t(W) * H * 3);
    film.develop(res.image.data(), res.variance.data());
    res.cancelled = cancelled;
    RenderStats& st = res.stats;
    st.time_s = secs;
    st.samples = samples.load();
    st.camera_rays = camera_rays.load();
    st.shadow_rays = shadow_rays.load();
    st.rays = rays.load();
    st.rays_per_s = secs > 0 ? double(st.rays) / secs : 0.0;
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
    st.spp = spp;
    st.seed = settings.seed;
    return res;
}

}  // namespace cmlt
