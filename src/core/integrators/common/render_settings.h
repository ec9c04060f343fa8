#pragma once
/// \file Render settings, results and statistics shared by all integrators.
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace cmlt {

namespace mlt {
struct ChainStates;  // integrators/mlt/chain_state.h
}

/// Settings of one frame. Each field: default, valid range.
struct RenderSettings {
    int width = 640;               ///< image width in pixels, >= 1
    int height = 480;              ///< image height in pixels, >= 1
    int spp = 16;                  ///< samples per pixel, >= 1
    double time_budget = 0.0;      ///< seconds, >= 0; > 0: the frame also stops when this
                                   ///< much time has passed (integrators/common/frame_loop.h)
    int max_depth = 64;            ///< max scattering events (pbrt): 1 = direct lighting, >= 1
    uint64_t seed = 0;             ///< RNG seed; same seed -> same image at any thread count
    int threads = 0;               ///< worker threads, 0 = all cores, >= 0
    std::string integrator = "pt"; ///< "pt" (path tracing with NEE + MIS), "bdpt" (bidirectional),
                                   ///< "pssmlt" (primary-sample-space MLT over PT's sampling;
                                   ///< `spp` = mutations per pixel, bootstrap included),
                                   ///< "cmlt" (coherent MLT; `spp` = path evaluations per pixel)

    // Metropolis (pssmlt). Defaults: pbrt-v4's published MLT defaults (shared/NOTES.md).
    double sigma = 0.01;                  ///< small-step Gaussian σ per primary sample, (0, 1]
    double large_step_probability = 0.3;  ///< probability of an independent (large) step, [0, 1]
    int chains = 1000;                    ///< Markov chains per frame, >= 1 (fixed: the image
                                          ///< does not depend on the thread count)
    int bootstrap_samples = 100000;       ///< large-step samples for b and the chain starts,
                                          ///< >= 1; at most half of spp·W·H is used
    std::string mlt_path_sampler = "bdpt";  ///< pssmlt's path sampler: "bdpt" (multiplexed
                                            ///< over depth and (s, t)) or "pt" (path tracer)
    /// pssmlt: start the chains from these states instead of resampling the bootstrap
    /// (one chain per state; integrators/mlt/chain_state.h). nullptr / empty: bootstrap.
    std::shared_ptr<const mlt::ChainStates> mlt_initial_states;
    /// Importance function of the chains (integrators/mlt/pixel_importance.h): "pixel"
    /// (f* = luminance / smoothed pilot brightness of the pixel: chains cover the image
    /// about uniformly) or "luminance" (f* = luminance, classic MLT).
    std::string importance = "pixel";
    /// Path-traced samples per pixel of the pilot image of the "pixel" importance, [1, 64];
    /// they count against the budget of path evaluations.
    int pilot_spp = 1;
    /// pssmlt/cmlt: share of the frame's path evaluations spent on the direct pass,
    /// [0, 0.9]. With f > 0, paths of 0 and 1 scattering events (emitters seen directly,
    /// direct lighting) are rendered by ordinary Monte Carlo (NEE + MIS, keyed samples,
    /// interleaved with the chains so it scales with a sample or a time budget) and the
    /// chains render depth >= 2 only; 0 = the chains render all.
    double direct_fraction = 0.3;
    /// The pilot image (H, W, 3) to use instead of rendering one (the temporal driver
    /// renders it once per frame for the render and its carry-over evaluations). Its
    /// cost is counted as if rendered (pilot_spp · W·H evaluations).
    std::shared_ptr<const std::vector<float>> pilot;

    // Coherent MLT (cmlt, DESIGN.md §3): after each outer large step, `inner_length`
    // inner steps of `tries` candidates each, drawn as one bundle by a lens / caustic
    // perturbation (σ_lens = sigma · max(W, H) pixels) or a pixel move.
    // Defaults: parameter study on sequences/cornell at equal time (see
    // integrators/cmlt/cmlt_integrator.h).
    int tries = 2;                 ///< k, candidates per inner step, [1, 64]
    int inner_length = 4;          ///< m, inner steps per outer step, >= 1
    std::string inner = "bundle";  ///< inner rule: "bundle" (multiple-proposal MH, exact),
                                   ///< "mtm" (Liu et al., exact), "seed" (the seminar's
                                   ///< 2k splats; biased, comparison only)
    bool packets = true;           ///< trace a bundle's rays (camera, walk bounces, shadow
                                   ///< rays) as Embree packets; off: one by one
                                   ///< (bit-identical image, for comparison)

    /// Throws SettingsError naming the bad field.
    void validate() const;
};

/// Statistics of a Metropolis render (pssmlt, cmlt).
struct MltStats {
    bool enabled = false;
    double b = 0, b_stderr = 0;                      ///< normalisation E[f*], bootstrap + large steps
    double b_bootstrap = 0, b_bootstrap_stderr = 0;  ///< from the bootstrap alone
    uint64_t bootstrap_samples = 0;                  ///< used (≤ the setting, ≤ half the budget)
    uint64_t bootstrap_nonzero = 0;                  ///< bootstrap samples with f* > 0
    uint64_t chains = 0;
    uint64_t mutations = 0;                          ///< Markov-chain steps taken
    double mutations_per_pixel = 0;                  ///< mutations / (W·H)
    double large_step_probability = 0, sigma = 0;
    uint64_t small_steps = 0, large_steps = 0;
    double acceptance_small = 0, acceptance_large = 0;  ///< fraction of steps that moved
    uint64_t max_rejection_streak = 0;               ///< longest run of rejections in a chain
    uint64_t long_streak_rejections = 0;             ///< rejections in runs longer than 1000
    std::string path_sampler;                        ///< pssmlt: "bdpt" | "pt"
    uint64_t imported_chains = 0;                    ///< chains started from given states
    uint64_t clamped_splats = 0;                     ///< splats beyond the film's range
    uint64_t states_visited = 0;                     ///< distinct chain states (runs)
    double top_occupancy = 0;                        ///< share of steps spent in the most-
                                                     ///< occupied 0.1 % of the states
    std::string importance;                          ///< "pixel" | "luminance"
    uint64_t pilot_evaluations = 0;                  ///< budget spent on the pilot image
    uint64_t direct_evaluations = 0;                 ///< budget spent on the direct pass
    int min_depth = 0;                               ///< shortest path the chains render
    double time_budget = 0;                          ///< seconds (0: none)
    std::string kernel_stats_json;                   ///< mlt::KernelStats::write_json (cmlt:
                                                     ///< + lens/caustic/pixel_move)
    // cmlt only
    int tries = 0, inner_length = 0;                 ///< k, m
    std::string inner;                               ///< inner rule
    bool packets = false;                            ///< bundles traced as packets
    int packet_width = 0;                            ///< widest packet used (1 = scalar)
    uint64_t packet_queries = 0;                     ///< packet calls (rtcIntersectN + rtcOccludedN)
    uint64_t packet_rays = 0;                        ///< rays answered by packets (active lanes)
    uint64_t packet_shadow_rays = 0;                 ///< of them, visibility rays (rtcOccludedN)
    uint64_t bundle_rays = 0;                        ///< rays of the inner chains' bundles
    double bundle_busy_s = 0;                        ///< CPU time evaluating bundles
    double bundle_trace_s = 0;                       ///< of it, inside BVH queries
    uint64_t path_evaluations = 0;                   ///< paths traced, bootstrap included
};

struct RenderStats {
    double time_s = 0;
    uint64_t samples = 0;       ///< pixel samples taken
    uint64_t camera_rays = 0;
    uint64_t shadow_rays = 0;
    uint64_t rays = 0;          ///< every BVH query (camera + bounce + shadow)
    uint64_t splats = 0;        ///< bdpt: light-tracing (t = 1) contributions splatted
    double rays_per_s = 0;
    /// CPU time summed over the worker threads: busy in the frame's parallel work, of it
    /// inside BVH queries (tracing), and the rest (shading: BSDFs, lights, sampling, MIS,
    /// splatting). Serial parts of the frame (setup, reductions) are in neither.
    double busy_s = 0, trace_s = 0, shade_s = 0;
    uint64_t nan_samples = 0;   ///< non-finite samples dropped by the film
    int first_nan_x = -1, first_nan_y = -1;
    int64_t first_nan_sample = -1;
    int threads = 0;
    std::string integrator;
    int spp = 0;
    uint64_t seed = 0;
    MltStats mlt;                  ///< filled by "pssmlt" only (mlt.enabled)
};

struct RenderResult {
    int width = 0, height = 0;
    std::vector<float> image;     ///< (H, W, 3), row 0 at the top
    std::vector<float> variance;  ///< (H, W, 3), sample variance of the pixel mean
    /// pssmlt / cmlt with a direct pass: its image (H, W, 3), already part of `image`
    /// (the rest is the chains', which the temporal driver rescales); else empty.
    std::vector<float> direct;
    /// pssmlt / cmlt: f* of every bootstrap sample, by index (keyed by (seed, bootstrap,
    /// i): with stored seeds the same points every frame, so two frames' values pair up
    /// — the temporal driver's change detection). Empty for pt / bdpt.
    std::vector<float> bootstrap_f;
    bool cancelled = false;
    RenderStats stats;
    /// pssmlt: the final state of every chain (integrators/mlt/chain_state.h).
    std::shared_ptr<mlt::ChainStates> mlt_states;
    /// pssmlt: the state every chain started the frame from (after resampling or import).
    std::shared_ptr<mlt::ChainStates> mlt_start_states;
};

/// Called from the calling thread between chunks with (done, total) samples per pixel;
/// return false to stop after the current chunk.
using ProgressCallback = std::function<bool(uint64_t done, uint64_t total)>;

}  // namespace cmlt
