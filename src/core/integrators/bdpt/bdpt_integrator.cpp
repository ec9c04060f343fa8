#include "integrators/bdpt/bdpt_integrator.h"

#include "accel/accel.h"
#include "cameras/camera.h"
#include "film/film.h"
#include "film/filter.h"
#include "film/pass_splatter.h"
#include "integrators/bdpt/bdpt_tracer.h"
#include "integrators/common/frame_loop.h"
#include "integrators/path/lens_light_tracing.h"
#include "scene/scene.h"

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>

namespace cmlt {

RenderResult render_bdpt(const Scene& scene, const RenderSettings& settings,
                         const ProgressCallback& progress) {
    const int W = settings.width, H = settings.height;
    const Camera camera(scene.camera_desc(), W, H);
    Film film(W, H);
    film.set_variance_block(variance_block(pixel_sequence(settings)));
    const PixelFilter filter = PixelFilter::from_settings(settings.pixel_filter, settings.filter_radius);
    // light tracing reaches the film window (the image and the filter's margin), its
    // importance normalised over the window
    BdptTracer tracer(scene, camera, W, H, settings.max_depth, filter.margin());
    const std::vector<uint32_t> lens_lights = LensLightTracing::sub_pixel_lights(scene, camera, W, H, filter.margin());
    tracer.set_direct_light_tracing(lens_lights);
    // auto: half the light subpaths aimed at the casters (README, "Caustics in bdpt")
    tracer.set_emission_guiding(settings.emission_guiding < 0.0 ? 0.5f : float(settings.emission_guiding));
    // a sample's shadow rays in Embree packets (--no-packets: one by one, bit for bit the scalar connect)
    tracer.set_packet_width(settings.packets ? Accel::max_packet_width() : 1);
    // every pass's camera samples go to the film through the splatter (film/pass_splatter.h):
    // a wide filter splats each to its neighbours (the window's source pixels are traced,
    // each sampled uniformly in its pixel); the one-pixel box keeps it in its pixel
    PassSplatter splatter(filter, film);
    // the pixels' sample keys follow the frame's film offset (pass_splatter.h KeyShift)
    splatter.set_key_shift(KeyShift::of(settings));
    const PixelFilter unit_box;
    const std::vector<Tile>& tiles = splatter.source_tiles();
    // one light subpath per traced pixel sample: the splats are scaled by the window's
    // area over their number (the image's pixels, or the splatter's source pixels)
    const double splat_scale = filter.window_area(W, H) / splatter.source_pixels();
    const int threads = frame_threads(settings);
    tbb::task_arena arena(threads);

    const size_t n_pix = size_t(W) * size_t(H);
    std::vector<double> splat_img(3 * n_pix);
    std::vector<std::vector<BdptSplat>> tile_splats(tiles.size());
    tbb::enumerable_thread_specific<BdptWorkspace> workspaces;

    FrameCounters counters;
    const CycleRate rate;
    const auto t0 = std::chrono::steady_clock::now();
    const PixelSequence sequence = pixel_sequence(settings);
    // Trace: one sample per pixel, splats kept per tile.
    const auto trace_pass = [&](int pass) {
        parallel_tasks(
            arena, counters, tiles.size(), size_t(1),
            [&](const tbb::blocked_range<size_t>& r) {
                BdptWorkspace& ws = workspaces.local();
                BdptCounters c;
                for (size_t ti = r.begin(); ti != r.end(); ++ti) {
                    const Tile& tile = tiles[ti];
                    std::vector<BdptSplat>& out = tile_splats[ti];
                    out.clear();
                    for (int y = tile.y0; y < tile.y1; ++y)
                        for (int x = tile.x0; x < tile.x1; ++x) {
                            PixelStreamSampler sampler(settings.seed, splatter.key(x, y), uint32_t(pass), sequence);
                            sampler.start_stream(BdptSampler::k_camera);
                            // the film position, uniform in the pixel (the light-tracing
                            // splats below are filtered where they land)
                            float weight = 1.f;
                            const Vec2 p_film = unit_box.film_position(x, y, sampler.next2d(), &weight);
                            ws.splats.clear();
                            splatter.set(x, y, p_film, tracer.li(p_film, sampler, ws, c), uint32_t(pass));
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
    };
    // Merge the splats in tile order (deterministic sums), each over the filter's
    // footprint around where it landed (the one pixel for the unit box).
    const auto merge_splats = [&] {
        std::fill(splat_img.begin(), splat_img.end(), 0.0);
        for (const auto& list : tile_splats)
            for (const BdptSplat& sp : list) filter.splat(sp.p_raster, sp.L, splat_scale, W, H, splat_img.data());
    };
    // One film sample per pixel: its pass estimate (splatted) + the light splats.
    const auto add_pass = [&](int pass) { splatter.gather(arena, uint32_t(pass), splat_img.data()); };
    bool cancelled = false;
    PassTarget target(settings, film);
    const int done = run_passes(PassSchedule(settings, t0), progress, &cancelled, [&](int s0, int s1) {
        for (int pass = s0; pass < s1; ++pass) {
            trace_pass(pass);
            merge_splats();
            add_pass(pass);
        }
    }, &target);

    RenderResult res = film_result(film, counters, rate, seconds_since(t0), settings, threads, done, cancelled, &target);
    if (splatter.active()) res.stats.pixel_correlation = filter.splat_correlation();
    res.stats.splats = counters.splats.load();
    res.stats.lens_lights = uint32_t(lens_lights.size());
    res.stats.emission_guiding = tracer.emission_guiding();
    res.stats.nan_samples += counters.bad_splats.load();
    return res;
}

}  // namespace cmlt
