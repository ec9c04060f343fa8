#pragma once
/// \file Whole-image path-tracing passes with independent keyed samples, for the
/// Metropolis integrators (pssmlt, cmlt): the pilot image of the pixel importance
/// (pixel_importance.h) and the direct pass (depths 0 and 1; the chains leave them to
/// ordinary Monte Carlo, where it beats a Markov chain — Mitsuba 0.5's PSSMLT does the
/// same). Each pass keys its samples from its own sample-index base (PixelSampler
/// counters (seed, pixel, base + s); k_pilot_sample_base and k_direct_sample_base in
/// sampling/rng_domains.h), so the passes never share numbers with each other or with
/// the pt integrator, and a static shot gets the same pass every frame.
///
/// The direct pass runs in slices between the chain rounds (DirectSchedule), so it keeps
/// its share of the frame's evaluations under a sample or a time budget.
#include "cameras/camera.h"
#include "film/film.h"
#include "film/filter.h"
#include "film/pass_splatter.h"
#include "integrators/common/frame_loop.h"
#include "integrators/path/caustic_light_tracing.h"
#include "integrators/path/lens_light_tracing.h"
#include "integrators/path/path_tracer.h"
#include "sampling/rng_domains.h"

#include <tbb/task_arena.h>

#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <vector>

namespace cmlt {

class Scene;
struct RenderSettings;

namespace mlt {

struct PtPassImage {
    std::vector<float> mean;      ///< (H, W, 3)
    std::vector<float> variance;  ///< (H, W, 3), variance of each pixel's mean
    std::vector<float> robust;    ///< (H, W, 3), mean without its largest and smallest pass (Film::develop)
    uint64_t nan_samples = 0;     ///< non-finite samples dropped
};

/// Path-traced samples keyed (seed, pixel, `sample_base` + s) of paths with at most
/// `max_depth` scattering events, accumulated over calls of render_to.
class PtPass {
public:
    PtPass(const Scene& scene, const RenderSettings& s, uint32_t sample_base, int max_depth);

    int passes() const { return m_passes; }
    /// Lights traced from the light side (enable_light_tracing; 0 without).
    uint32_t lens_lights() const { return m_lens ? uint32_t(m_lens->lights().size()) : 0u; }
    /// Casters the pass's caustic light tracing aims at (enable_light_tracing; 0: none traced).
    uint32_t caustic_casters() const { return m_caustic ? uint32_t(m_caustic->caster_count()) : 0u; }
    /// The pass's caustic light tracing (enable_light_tracing), or null.
    const CausticLightTracing* caustic_light_tracing() const { return m_caustic.get(); }
    /// Path evaluations so far (passes · W·H).
    uint64_t evaluations() const;
    /// Render passes up to `total` (no-op if already there), rays into `counters`.
    void render_to(tbb::task_arena& arena, int total, FrameCounters& counters);
    /// Mean and variance of the mean (H, W, 3), with `robust` also the trimmed mean
    /// (Film::develop); empty before the first pass.
    PtPassImage develop(bool robust = false) const;
    /// The film the passes accumulate into.
    const Film& film() const { return m_film; }
    /// Render only rows [y0, y1) (a part of a frame, RenderSettings::partial; the other
    /// rows stay 0). Default: every row.
    void set_rows(int y0, int y1) {
        m_row0 = y0;
        m_row1 = y1;
    }

protected:
    /// Trace the scene's sub-pixel lights from the light side too (BDPT's (1, 1)
    /// strategy, path/lens_light_tracing.h): a light sample per pixel sample, splatted,
    /// and the camera's hits on those lights MIS-weighted against it; with `caustic`,
    /// the caustics too, as the pt integrator does (path/caustic_light_tracing.h: only
    /// for a pass whose class holds every path the light paths make — every path, or the
    /// easy part with the light-traced caustics, PathPartition::set_traced).
    /// Nothing changes when the scene has no such light or caster. Before the first pass.
    void enable_light_tracing(const Scene& scene, bool caustic);
    /// Render only the paths of one class (PathTracer::set_partition; the object must
    /// outlive the pass; null: every path).
    void set_partition(const PathPartition* partition);

    const RenderSettings& m_settings;

private:
    /// render_to with lens light tracing or a wide filter: pass by pass, each pass's
    /// light-tracing splats added to its pixel samples (as the bdpt integrator does), so
    /// the variance sees them, and its camera samples splatted over the filter's
    /// footprint (film/pass_splatter.h).
    void render_passes_indexed(tbb::task_arena& arena, int s0, int s1, FrameCounters& counters);

    const Scene& m_scene;
    Camera m_camera;
    PixelFilter m_filter;
    PathTracer m_tracer;
    std::unique_ptr<LensLightTracing> m_lens;          ///< with light passes (active or not)
    std::unique_ptr<CausticLightTracing> m_caustic;    ///< caustic light tracing, if on and active
    std::unique_ptr<LensPass> m_lens_pass;             ///< the light passes' splats per pass
    bool m_motion_blur;
    Film m_film;
    std::unique_ptr<PassSplatter> m_splatter;  ///< made at the first indexed pass (rows known)
    uint32_t m_sample_base;
    int m_passes = 0;
    int m_row0 = 0, m_row1 = -1;  ///< rows rendered (-1: the image's height)
};

/// The packet width of the Metropolis integrators' path-traced passes (the pilot and the
/// direct pass): Embree's widest, whatever RenderSettings::packets says. `packets` turns
/// the chains' packets on and off — their scalar reference, bit for bit — and these
/// passes are the same in both, so the frame is too. (Embree's packet and single-ray
/// kernels give the same hits on every sequence of the repository, but not on every
/// scene: on tests/data/usd/polygons.usda a few rays differ.) Tracing these passes one
/// query at a time made cmlt and pssmlt 1.16-1.41x slower per frame.
int pt_pass_packet_width();

/// The pilot image: `spp` samples per pixel at full depth, keyed from
/// k_pilot_sample_base (H, W, 3). Adds its rays to `counters`.
std::vector<float> render_pilot(const Scene& scene, const RenderSettings& settings, int spp,
                                PathCounters& counters);

/// The direct pass of a Metropolis frame, keyed from k_direct_sample_base: depths 0
/// and 1, or, when the chains render only caustic paths (mlt_paths caustics / none),
/// every other path at every depth (path_partition.h), with the caustics pt's caustic
/// light tracing makes and that light tracing (RenderSettings::mlt_traced_caustics
/// "direct"); disabled when direct_fraction is 0 and the chains render every longer path.
class DirectPass : public PtPass {
public:
    DirectPass(const Scene& scene, const RenderSettings& s);
    bool enabled() const { return m_enabled; }
    /// Passes a time-budgeted frame should have after `chain_evaluations`: the share
    /// direct_fraction of all evaluations (at least one).
    int passes_for(uint64_t chain_evaluations) const;

private:
    bool m_enabled;
    PathPartition m_partition;  ///< easy paths when the chains render the caustic ones
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

    void before_round(const ChainSchedule& rounds, uint64_t chain_evaluations);
    void finish(bool cancelled, bool chains_ran, std::chrono::steady_clock::time_point t0);
    /// A frame without chains (mlt_paths none, or none started): the pass renders the
    /// frame as pt's frame loop does — chunks of passes up to `passes` (0: the settings'
    /// spp; with a time budget, until it is used), a target error from the pass's own
    /// variance (PassTarget), `progress` able to stop it (*cancelled). Returns whether
    /// the target error was reached; its history goes to `history`.
    bool run_alone(const ProgressCallback& progress, std::chrono::steady_clock::time_point t0, bool* cancelled,
                   std::vector<std::array<double, 4>>* history, int passes = 0);
};

}  // namespace mlt
}  // namespace cmlt
