// Keyed path-tracing passes of the Metropolis frames; see direct_pass.h.
#include "integrators/mlt/direct_pass.h"

#include "accel/accel.h"
#include "integrators/common/render_settings.h"
#include "integrators/mlt/mlt_context.h"
#include "integrators/path/path_batch.h"
#include "scene/scene.h"
#include "util/error.h"

#include <algorithm>
#include <cmath>

#include <tbb/enumerable_thread_specific.h>

namespace cmlt::mlt {

int pt_pass_packet_width() { return Accel::max_packet_width(); }

PtPass::PtPass(const Scene& scene, const RenderSettings& s, uint32_t sample_base, int max_depth)
    : m_settings(s), m_scene(scene), m_camera(scene.camera_desc(), s.width, s.height),
      m_filter(PixelFilter::from_settings(s.pixel_filter, s.filter_radius)), m_tracer(scene, max_depth),
      m_motion_blur(scene.motion_blur()), m_film(s.width, s.height), m_sample_base(sample_base) {
    m_tracer.set_sequence(pixel_sequence(s));
    m_film.set_variance_block(variance_block(pixel_sequence(s)));
}

uint64_t PtPass::evaluations() const {
    return uint64_t(m_passes) * uint64_t(m_settings.width) * uint64_t(m_settings.height);
}

void PtPass::enable_light_tracing(const Scene& scene, bool caustic) {
    CMLT_CHECK_MSG(m_passes == 0, "PtPass::enable_light_tracing after " << m_passes << " passes");
    const int W = m_settings.width, H = m_settings.height;
    auto lens = std::make_unique<LensLightTracing>(scene, m_camera, W, H, m_filter.margin());
    std::unique_ptr<CausticLightTracing> traced;
    if (caustic) {
        traced = std::make_unique<CausticLightTracing>(scene, m_camera, W, H, m_filter.margin(), m_tracer.max_depth());
        if (!traced->active()) traced.reset();
    }
    m_tracer.set_lens_light_tracing(lens->active() ? lens.get() : nullptr);
    m_tracer.set_caustic_light_tracing(traced.get());
    if (!lens->active() && !traced) {
        m_lens_pass.reset();
        m_caustic.reset();
        m_lens.reset();
        return;
    }
    m_lens_pass = std::make_unique<LensPass>(*lens, m_filter, W, H, traced.get());
    m_lens = std::move(lens);
    m_caustic = std::move(traced);
}

void PtPass::set_partition(const PathPartition* partition) { m_tracer.set_partition(partition); }

void PtPass::render_passes_indexed(tbb::task_arena& arena, int s0, int s1, FrameCounters& counters) {
    const int W = m_settings.width, H = m_settings.height;
    const int y0 = m_row0, y1 = m_row1 < 0 ? H : m_row1;
    if (!m_splatter) {
        m_splatter = std::make_unique<PassSplatter>(m_filter, m_film, y0, y1);
        m_splatter->set_key_shift(KeyShift::of(m_settings));  // keys follow the film offset
    }
    // camera samples, each uniform in its pixel: this part's rows (and, with a wide
    // filter, the source rows around them and the window's columns: film/pass_splatter.h),
    // tile by tile in PathBatch's lanes, queries in packets (pt_pass_packet_width)
    const PixelFilter unit_box;
    const std::vector<Tile>& src_tiles = m_splatter->source_tiles();
    const int width = pt_pass_packet_width();
    tbb::enumerable_thread_specific<PathBatch> batches([&] {
        return PathBatch(m_tracer, m_scene, m_camera, unit_box, m_motion_blur, m_settings.seed, W, H,
                         m_splatter->reach(), width, KeyShift::of(m_settings));
    });
    for (int k = s0; k < s1; ++k) {
        const uint32_t index = m_sample_base + uint32_t(k);
        parallel_tasks(arena, counters, src_tiles.size(), size_t(1), [&](const tbb::blocked_range<size_t>& r) {
            PathCounters c;
            PathBatch& batch = batches.local();
            for (size_t ti = r.begin(); ti != r.end(); ++ti) batch.trace_tile_to(src_tiles[ti], index, c, *m_splatter);
            counters.add(c);
        });
        // light samples (lens light tracing): every pixel of the frame
        const double* splats =
            m_lens_pass ? m_lens_pass->trace(arena, counters, m_settings.seed, index, m_motion_blur) : nullptr;
        m_splatter->gather(arena, index, splats);
    }
}

void PtPass::render_to(tbb::task_arena& arena, int total, FrameCounters& counters) {
    if (total <= m_passes) return;
    if (m_lens || !m_filter.unit_box()) {
        render_passes_indexed(arena, m_passes, total, counters);
        m_passes = total;
        return;
    }
    const int s0 = m_passes, s1 = total, W = m_settings.width, H = m_settings.height;
    const int y0 = m_row0, y1 = m_row1 < 0 ? H : m_row1;
    // this part's rows, tile by tile, each tile's samples in PathBatch's lanes (queries in
    // packets: pt_pass_packet_width); the keys follow the film offset
    std::vector<Tile> tiles;
    for (Tile t : image_tiles(W, H)) {
        t.y0 = std::max(t.y0, y0);
        t.y1 = std::min(t.y1, y1);
        if (t.y0 < t.y1) tiles.push_back(t);
    }
    const int width = pt_pass_packet_width();
    parallel_tasks(arena, counters, tiles.size(), size_t(1), [&](const tbb::blocked_range<size_t>& r) {
        PathCounters c;
        PathBatch batch(m_tracer, m_scene, m_camera, m_filter, m_motion_blur, m_settings.seed, W, H, 0, width,
                        KeyShift::of(m_settings));
        // a pixel's samples arrive in sample order (film.h)
        for (size_t ti = r.begin(); ti != r.end(); ++ti)
            for (int k = s0; k < s1; ++k) batch.trace_tile_to(tiles[ti], m_sample_base + uint32_t(k), c, m_film);
        counters.add(c);
    });
    m_passes = total;
}

PtPassImage PtPass::develop(bool robust) const {
    PtPassImage out;
    if (m_passes == 0) return out;
    const size_t n = size_t(m_settings.width) * size_t(m_settings.height) * 3;
    out.mean.resize(n);
    out.variance.resize(n);
    if (robust) out.robust.resize(n);
    m_film.develop(out.mean.data(), out.variance.data(), robust ? out.robust.data() : nullptr);
    out.nan_samples = m_film.nan_samples();
    return out;
}

std::vector<float> render_pilot(const Scene& scene, const RenderSettings& settings, int spp,
                                PathCounters& counters) {
    PtPass pass(scene, settings, k_pilot_sample_base, settings.max_depth);
    tbb::task_arena arena(frame_threads(settings));
    FrameCounters c;
    pass.render_to(arena, spp, c);
    counters += c.paths();
    std::vector<float> mean = pass.develop().mean;
    if (mean.empty()) mean.assign(size_t(settings.width) * size_t(settings.height) * 3, 0.f);
    return mean;
}

DirectPass::DirectPass(const Scene& scene, const RenderSettings& s)
    : PtPass(scene, s, k_direct_sample_base, MltContext::direct_max_depth(s)),
      m_enabled(MltContext::direct_spp(s) > 0),
      // the chains' caustic paths left out only where there are chains (a chainless
      // frame's pass is the only estimator: every path)
      m_partition(scene, MltContext::partitioned(s) && !MltContext::chainless(s) ? PathPart::easy : PathPart::all,
                  s.mlt_sds == "direct") {
    if (s.partial) set_rows(s.part_row_begin, s.part_row_end);  // a part of the frame
    set_partition(&m_partition);
    // a chainless frame renders every path here: pt's caustic light tracing too; beside
    // chains, the caustic paths that light tracing makes (MltContext's partition gets the
    // same traced lights from the same tracer)
    if (!m_enabled) return;
    const bool traced = MltContext::traced_to_direct(s);
    enable_light_tracing(scene, (MltContext::chainless(s) && s.caustic_tracing) || traced);
    if (traced && caustic_light_tracing()) m_partition.set_traced(caustic_light_tracing()->traced_lights());
}

int DirectPass::passes_for(uint64_t chain_evaluations) const {
    const double f = MltContext::direct_fraction(m_settings);
    const double pixels = double(m_settings.width) * double(m_settings.height);
    return std::max(1, int(std::ceil(f / (1.0 - f) * double(chain_evaluations) / pixels)));
}

void DirectSchedule::before_round(const ChainSchedule& rounds, uint64_t chain_evaluations) {
    if (!pass.enabled()) return;
    if (rounds.timed()) pass.render_to(arena, pass.passes_for(chain_evaluations), counters);
    else if (rounds.targeted())
        pass.render_to(arena, int(std::ceil(MltContext::direct_spp(settings) * rounds.fraction())), counters);
    else pass.render_to(arena, MltContext::direct_spp(settings) * (rounds.round() + 1) / ChainSchedule::k_rounds,
                        counters);
}

void DirectSchedule::finish(bool cancelled, bool chains_ran, std::chrono::steady_clock::time_point t0) {
    if (!pass.enabled() || cancelled) return;
    if (settings.time_budget <= 0.0) {
        pass.render_to(arena, MltContext::direct_spp(settings), counters);
        return;
    }
    if (chains_ran) return;
    const PassSchedule time(settings, t0);
    while (const int n = time.next(pass.passes())) pass.render_to(arena, pass.passes() + n, counters);
}

bool DirectSchedule::run_alone(const ProgressCallback& progress, std::chrono::steady_clock::time_point t0,
                               bool* cancelled, std::vector<std::array<double, 4>>* history, int passes) {
    RenderSettings s = settings;
    if (passes > 0 && s.time_budget <= 0.0) s.spp = passes;
    const PassSchedule schedule(s, t0);
    PassTarget target(settings, pass.film());
    run_passes(schedule, progress, cancelled, [&](int, int s1) { pass.render_to(arena, s1, counters); }, &target);
    if (history) *history = target.target.take_history();
    return target.reached;
}

}  // namespace cmlt::mlt
