// Whole-image path-tracing passes; see pt_pass.h.
#include "integrators/path/pt_pass.h"

#include "cameras/camera.h"
#include "film/film.h"
#include "integrators/common/render_settings.h"
#include "scene/scene.h"
#include "util/fp_mode.h"

#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <atomic>

namespace cmlt {

PtPassImage render_pt_pass(const Scene& scene, const RenderSettings& settings, int spp,
                           uint32_t sample_base, int max_depth, PathCounters& counters) {
    const int W = settings.width, H = settings.height;
    PtPassImage out;
    out.mean.assign(size_t(W) * size_t(H) * 3, 0.f);
    out.variance.assign(size_t(W) * size_t(H) * 3, 0.f);
    if (spp < 1) return out;
    const Camera camera(scene.camera_desc(), W, H);
    const PathTracer tracer(scene, max_depth);
    const bool motion_blur = scene.motion_blur();
    Film film(W, H);
    const int threads = settings.threads > 0 ? settings.threads : tbb::info::default_concurrency();
    tbb::task_arena arena(threads);
    std::atomic<uint64_t> camera_rays{0}, shadow_rays{0}, rays{0}, samples{0};
    arena.execute([&] {
        tbb::parallel_for(tbb::blocked_range<int>(0, H, 2), [&](const tbb::blocked_range<int>& r) {
            ScopedFtzDaz ftz;
            PathCounters c;
            for (int y = r.begin(); y != r.end(); ++y)
                for (int x = 0; x < W; ++x)
                    for (int s = 0; s < spp; ++s) {
                        const uint32_t index = sample_base + uint32_t(s);
                        film.add_sample(x, y, index,
                                        tracer.pixel_sample(camera, motion_blur, settings.seed, x, y, W, index, c));
                    }
            camera_rays.fetch_add(c.camera_rays, std::memory_order_relaxed);
            shadow_rays.fetch_add(c.shadow_rays, std::memory_order_relaxed);
            rays.fetch_add(c.rays, std::memory_order_relaxed);
            samples.fetch_add(c.samples, std::memory_order_relaxed);
        });
    });
    film.develop(out.mean.data(), out.variance.data());
    out.nan_samples = film.nan_samples();
    counters.camera_rays += camera_rays.load();
    counters.shadow_rays += shadow_rays.load();
    counters.rays += rays.load();
    counters.samples += samples.load();
    return out;
}

}  // namespace cmlt
