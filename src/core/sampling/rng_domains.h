#pragma once
/// \file The registry of random-number streams: every Philox counter space the renderer
/// draws from, in one place, so that no two consumers ever share a number by accident
/// and a new one can see which spaces are taken. All are keyed by the shot seed
/// (philox.h's seed_key) and never by the frame,
/// so consecutive frames of a shot reuse the same numbers (DESIGN.md §4, stored seeds).
///
/// Two counter layouts, told apart by the last word:
///
/// 1. Pixel samples, counter (pixel, sample index, dimension, stream): PixelSampler
///    (path tracer, pilot, direct pass, AOVs) and PixelStreamSampler (BDPT). The last
///    word is a small stream id (RngStream, < 2^16).
///    * sample index: the pt and bdpt integrators use 0, 1, ..; the Metropolis passes
///      start at their own bases (k_direct_sample_base, k_pilot_sample_base), far above
///      any sample count, so they never meet the integrators' samples or each other;
///    * dimension: a path reads dimensions 0, 1, .. in order; the camera's lens and
///      shutter-time numbers have reserved dimensions far above (k_lens_dimension,
///      k_shutter_time_dimension), so drawing them or not leaves every other number as
///      it is (a scene without the feature renders bit-identically).
///
/// 2. Metropolis numbers, counter (id, draw low, index, tag << 24 | domain << 16 | draw
///    high) (metropolis_counter): MltSampler's primary samples, coherent MLT's keyed
///    states, the chains' sequential numbers (CounterRng) and the temporal carry-over.
///    The tag byte starts at 0x10 (RngTag), so the last word is ≥ 2^28: these counters
///    never meet the pixel samples'. Within it:
///    * tag: which draw of a primary sample (RngTag: a large step's value, a small
///      step's Gaussian), the sequential stream of a chain, or a keyed uniform of the
///      carry-over;
///    * domain (8 bits, RngDomain): which population — bootstrap sample, chain,
///      resampling, carry-over evaluation, carry-over keep tests and refresh draws;
///    * id: the index inside the domain (bootstrap sample i, chain c, ...);
///    * draw: the proposal number (MltSampler, coherent MLT's keys) or the draw count
///      (CounterRng), 48 bits;
///    * index: the global primary-sample index (MltSampler layout), 0 for CounterRng.
#include "sampling/philox.h"

#include <cstdint>

namespace cmlt {

// ---- 1. pixel samples -----------------------------------------------------------------

/// Stream ids of the pixel-sample counters (the counter's last word).
enum class RngStream : uint32_t {
    camera_path = 0,       ///< PixelSampler: a path-traced pixel sample (film, lens, time, bounces)
    bdpt_camera = 16,      ///< PixelStreamSampler: BDPT's camera subpath
    bdpt_light = 17,       ///< PixelStreamSampler: BDPT's light subpath
    bdpt_connection = 18,  ///< PixelStreamSampler: BDPT's connections
    lens_light = 19,       ///< LensLightTracing: the light sample of a direct-pass pixel sample
    caustic_light = 20,    ///< CausticLightTracing: the light path of a pt pixel sample
    test = 0xFFFF,         ///< tests' own numbers (tests/cpp)
};

/// Sample-index bases of the Metropolis integrators' path-traced passes (direct_pass.h):
/// top bits, disjoint from the pt integrator's 0.. and from each other.
inline constexpr uint32_t k_direct_sample_base = 0xA0000000u;
inline constexpr uint32_t k_pilot_sample_base = 0xC0000000u;

/// The sample word of the counters that seed the scrambles of a pixel's low-discrepancy
/// sequence (RenderSettings::sampler "sobol", sampling/sobol.h): sobol::scramble_seeds
/// of counter (pixel, k_sequence_seed_sample, dimension, stream) gives one dimension's
/// seed words (a hash of the counter, not Philox: these counters never give Philox
/// numbers). With the sequence in blocks of B samples ("sobol-blocks"), block k's are
/// counter (pixel, k_sequence_seed_sample − k, dimension, stream): for any sample below
/// 0xE0000000 (the top of the pilot's range) that stays above 0xE0000000 too, apart from
/// every sample index a pass uses (the bases above leave 2^29 samples and more below them).
inline constexpr uint32_t k_sequence_seed_sample = 0xFFFFFFFFu;

/// Motion blur: the shutter time of a camera sample (Ray::time, in [0, 1) over
/// [shutter open, shutter close]) is drawn from its own dimension of the sample's
/// camera-path stream, far above any dimension a path uses, and only when the scene has
/// motion-blurred geometry (Scene::motion_blur()).
inline constexpr uint32_t k_shutter_time_dimension = 0xFFFFFF00u;
/// Thin lens: the 2-D lens position of a camera sample (Camera::has_lens), drawn only
/// with a lens.
inline constexpr uint32_t k_lens_dimension = 0xFFFFFF10u;

inline Philox4x32Counter pixel_counter(uint32_t pixel, uint32_t sample, uint32_t dimension, RngStream stream) {
    return {pixel, sample, dimension, uint32_t(stream)};
}

// ---- 2. Metropolis numbers --------------------------------------------------------------

/// Which draw of the Metropolis counters (the high byte of the last word is 0x10 + tag).
enum class RngTag : uint32_t {
    point = 0,       ///< a primary sample's refresh and large-step values (MltSampler, keyed states)
    sequence = 1,    ///< a chain's sequential numbers (CounterRng)
    small_step = 2,  ///< a primary sample's small-step Gaussian (MltSampler)
    keyed = 3,       ///< one keyed uniform (temporal::keyed_uniform)
    lazy_step = 4,   ///< a coherent-MLT state's lazy small step or refresh (cmlt_state.h)
};

/// Populations of the Metropolis counters (`id` is the index inside one).
enum class RngDomain : uint32_t {
    bootstrap = 1,          ///< id = bootstrap sample index (pssmlt and cmlt: the same points)
    chain = 2,              ///< id = chain index
    resample = 3,           ///< id = 0: resampling the chains' start states
    bootstrap_probe = 4,    ///< id = probe sample index (mlt_frame.h bootstrap_size)
    carry_evaluate = 0x40,  ///< temporal/carry.h: id = carried state index
    carry_keep = 0x43,      ///< temporal/carry.h: id = chain, draw = frame key: keep tests
    carry_refresh = 0x44,   ///< temporal/carry.h: id = group, draw = frame key: refresh draws
    test = 0xFF,            ///< tests' own chains (tests/cpp)
};

inline Philox4x32Counter metropolis_counter(RngTag tag, RngDomain domain, uint32_t id, uint64_t draw,
                                            uint32_t index) {
    return {id, uint32_t(draw), index,
            ((0x10u + uint32_t(tag)) << 24) | ((uint32_t(domain) & 0xFFu) << 16) | uint32_t((draw >> 32) & 0xFFFFu)};
}

}  // namespace cmlt
