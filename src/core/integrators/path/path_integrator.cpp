// The path-tracing frame loop; see path_integrator.h.
#include "integrators/path/path_integrator.h"

#include "cameras/camera.h"
#include "film/film.h"
#include "film/filter.h"
#include "film/pass_splatter.h"
#include "integrators/common/frame_loop.h"
#include "accel/accel.h"
#include "integrators/path/caustic_light_tracing.h"
#include "integrators/path/lens_light_tracing.h"
#include "integrators/path/path_batch.h"
#include "integrators/path/path_tracer.h"
#include "scene/scene.h"

#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <chrono>
#include <memory>

namespace cmlt {

RenderResult render_pt(const Scene& scene, const RenderSettings& settings, const ProgressCallback& progress) {
    const int W = settings.width, H = settings.height;
    const Camera camera(scene.camera_desc(), W, H);
    Film film(W, H);
    film.set_variance_block(variance_block(pixel_sequence(settings)));
    const PixelFilter filter = PixelFilter::from_settings(settings.pixel_filter, settings.filter_radius);
    PathTracer tracer(scene, settings.max_depth);
    tracer.set_sequence(pixel_sequence(settings));
    // Lights smaller than a pixel are traced from the light side too (BDPT's (1, 1)
    // strategy, lens_light_tracing.h): camera rays almost never hit them. Without such a
    // light nothing changes.
    const LensLightTracing lens(scene, camera, W, H, filter.margin());
    if (lens.active()) tracer.set_lens_light_tracing(&lens);
    // Caustics (light reaching a rough surface through a mirror or glass bounce) are
    // traced from the light side too, MIS-weighted against the camera paths that find
    // them (caustic_light_tracing.h). Without a caster or a finite light nothing changes.
    const CausticLightTracing caustic(scene, camera, W, H, filter.margin(), settings.max_depth);
    const bool caustic_on = settings.caustic_tracing && caustic.active();
    if (caustic_on) tracer.set_caustic_light_tracing(&caustic);
    const bool light_passes = lens.active() || caustic_on;
    const bool motion_blur = scene.motion_blur();  // draw a shutter time per sample?
    std::vector<Tile> tiles = image_tiles(W, H);
    if (settings.partial) {
        // a part of the frame: only rows [part_row_begin, part_row_end); the rest stay 0
        std::vector<Tile> part;
        for (Tile t : tiles) {
            t.y0 = std::max(t.y0, settings.part_row_begin);
            t.y1 = std::min(t.y1, settings.part_row_end);
            if (t.y0 < t.y1) part.push_back(t);
        }
        tiles = std::move(part);
    }
    const int threads = frame_threads(settings);
    tbb::task_arena arena(threads);

    // Chunks of samples per pixel: about 16 progress calls per frame (frame_loop.h).
    FrameCounters counters;
    const CycleRate rate;
    const auto t0 = std::chrono::steady_clock::now();
    bool cancelled = false;
    PassTarget target(settings, film);
    // Paths in batches of a tile's pixel samples, queries in Embree packets
    // (path_batch.h); without packets one query at a time, li's image bit for bit.
    const int packet_width = settings.packets ? Accel::max_packet_width() : 1;
    int done = 0;
    PassSplatter splatter(filter, film, settings.partial ? settings.part_row_begin : 0,
                          settings.partial ? settings.part_row_end : H);
    // the pixels' sample keys follow the frame's film offset (pass_splatter.h KeyShift)
    const KeyShift shift = KeyShift::of(settings);
    splatter.set_key_shift(shift);
    if (!splatter.active() && !light_passes) {
        done = run_passes(PassSchedule(settings, t0), progress, &cancelled, [&](int s0, int s1) {
            parallel_tasks(
                arena, counters, tiles.size(), size_t(1),
                [&](const tbb::blocked_range<size_t>& r) {
                    PathCounters c;
                    PathBatch batch(tracer, scene, camera, filter, motion_blur, settings.seed, W, H, 0, packet_width, shift);
                    // a pixel's samples arrive in sample order (film.h)
                    for (size_t ti = r.begin(); ti != r.end(); ++ti)
                        for (int s = s0; s < s1; ++s) batch.trace_tile_to(tiles[ti], uint32_t(s), c, film);
                    counters.add(c, 0, batch.packets());
                    counters.lane_hits.fetch_add(batch.lane_hits(), std::memory_order_relaxed);
                },
                tbb::simple_partitioner());
        }, &target);
    } else {
        // A wide filter or light tracing: pass by pass, every source pixel of the window
        // (the image and the filter's ring) sampled uniformly in its pixel, then
        // splatted to its neighbours (film/pass_splatter.h), with the pass's light splats.
        const PixelFilter unit_box;
        std::unique_ptr<LensPass> lens_pass =
            light_passes ? std::make_unique<LensPass>(lens, filter, W, H, caustic_on ? &caustic : nullptr) : nullptr;
        const std::vector<Tile>& src_tiles = splatter.source_tiles();
        // a batch per thread for the frame (a pass is short: no allocation per tile)
        tbb::enumerable_thread_specific<PathBatch> batches([&] {
            return PathBatch(tracer, scene, camera, unit_box, motion_blur, settings.seed, W, H, splatter.reach(),
                             packet_width, shift);
        });
        done = run_passes(PassSchedule(settings, t0), progress, &cancelled, [&](int s0, int s1) {
            for (int s = s0; s < s1; ++s) {
                parallel_tasks(
                    arena, counters, src_tiles.size(), size_t(1),
                    [&](const tbb::blocked_range<size_t>& r) {
                        PathCounters c;
                        PathBatch& batch = batches.local();
                        const uint64_t packets0 = batch.packets(), lanes0 = batch.lane_hits();
                        for (size_t ti = r.begin(); ti != r.end(); ++ti)
                            batch.trace_tile_to(src_tiles[ti], uint32_t(s), c, splatter);
                        counters.add(c, 0, batch.packets() - packets0);
                        counters.lane_hits.fetch_add(batch.lane_hits() - lanes0, std::memory_order_relaxed);
                    },
                    tbb::simple_partitioner());
                const double* splats =
                    lens_pass ? lens_pass->trace(arena, counters, settings.seed, uint32_t(s), motion_blur) : nullptr;
                splatter.gather(arena, uint32_t(s), splats);
            }
        }, &target);
    }
    RenderResult res = film_result(film, counters, rate, seconds_since(t0), settings, threads, done, cancelled, &target);
    if (splatter.active()) res.stats.pixel_correlation = filter.splat_correlation();
    res.stats.lens_lights = uint32_t(lens.lights().size());
    res.stats.caustic_casters = caustic_on ? uint32_t(caustic.caster_count()) : 0u;
    return res;
}

}  // namespace cmlt
