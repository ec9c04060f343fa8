#pragma once
/// \file A whole-image path-tracing pass with independent keyed samples, for the
/// Metropolis integrators' helpers: the pilot image of the pixel importance
/// (mlt/pixel_importance.h) and the direct-lighting pass (depths 0 and 1; mlt/ leaves
/// them to ordinary Monte Carlo, where it beats a Markov chain — Mitsuba 0.5's PSSMLT
/// does the same). Each pass keys its samples from its own `sample_base` (PixelSampler
/// counters (seed, pixel, sample_base + s)), so passes never share numbers with each
/// other or with the `pt` integrator, and a static shot gets the same pass every frame.
#include "integrators/path/path_tracer.h"

#include <cstdint>
#include <vector>

namespace cmlt {

class Scene;
struct RenderSettings;

/// Sample-index bases of the passes (top bits: disjoint from the pt integrator's 0..).
inline constexpr uint32_t k_pilot_sample_base = 0xC0000000u;
inline constexpr uint32_t k_direct_sample_base = 0xA0000000u;

struct PtPassImage {
    std::vector<float> mean;      ///< (H, W, 3)
    std::vector<float> variance;  ///< (H, W, 3), variance of each pixel's mean
    uint64_t nan_samples = 0;     ///< non-finite samples dropped
};

/// `spp` samples per pixel of paths with at most `max_depth` scattering events, at the
/// settings' resolution, seed and thread count. Adds its rays to `counters`.
PtPassImage render_pt_pass(const Scene& scene, const RenderSettings& settings, int spp,
                           uint32_t sample_base, int max_depth, PathCounters& counters);

}  // namespace cmlt
