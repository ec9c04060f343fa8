#pragma once
/// \file Coherent MLT's settings of one frame: the RenderSettings fields it reads, in the
/// units its chains use, and the constants of its inner chain.
///
/// Defaults of the user settings (k = tries, m = inner_length, σ = sigma) come from the
/// equal-time study in tests/bench/results/cmlt_parameters.md (render_settings.h holds
/// them); the constants below from tests/bench/results/cmlt_small_steps.md.
#include "accel/accel.h"
#include "integrators/cmlt/inner_rule.h"
#include "integrators/common/render_settings.h"

#include <algorithm>
#include <cstddef>
#include <cstdint>

namespace cmlt::coherent {

/// Probability that an inner step is a pixel move (instead of a lens / caustic
/// perturbation or a small step; perturbations.h).
inline constexpr double k_pixel_move_probability = 0.1;

/// Probability that an inner step is a small step of every coordinate (PSSMLT's
/// Gaussian mutation as a bundle) instead of a lens / caustic perturbation.
inline constexpr double k_small_step_probability = 0.5;

struct CmltSettings {
    uint64_t seed = 0;
    int width = 0, height = 0;
    size_t tries = 2;          ///< k, candidates per inner step
    int inner_length = 4;      ///< m, inner steps per outer step
    InnerRule rule = k_default_inner_rule;
    double sigma_pixels = 0;   ///< lens perturbation σ in pixels: sigma · max(W, H)
    double sigma_primary = 0;  ///< caustic and small-step σ in primary-sample units
    bool packets = true;       ///< bundles traced as Embree packets
    int max_width = 4;         ///< widest native packet (Accel::max_packet_width)

    explicit CmltSettings(const RenderSettings& s)
        : seed(s.seed), width(s.width), height(s.height), tries(size_t(s.tries)), inner_length(s.inner_length),
          rule(parse_inner_rule(s.inner)), sigma_pixels(s.sigma * double(std::max(s.width, s.height))),
          sigma_primary(s.sigma), packets(s.packets), max_width(Accel::max_packet_width()) {}

    /// Path evaluations of a chain's block, its outer step and inner chain: about 1 + m·k.
    uint64_t block_cost() const { return 1 + uint64_t(inner_length) * uint64_t(tries); }
};

}  // namespace cmlt::coherent
