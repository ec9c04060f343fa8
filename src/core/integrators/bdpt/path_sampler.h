#pragma once
/// \file Independent numbers for BDPT's three streams (the BdptSampler interface,
/// base/sampler.h): the pixel samples of the bdpt integrator. The Metropolis integrators
/// drive the same code with their primary samples (BdptStreamAdapter, pssmlt_tracer.h).
#include "base/sampler.h"
#include "math/vec.h"
#include "sampling/rng.h"

#include <cstdint>

namespace cmlt {

/// The numbers of one pixel sample: counter (pixel, sample, dimension,
/// RngStream::bdpt_camera + stream) (sampling/rng_domains.h), independent (Philox keyed
/// by the seed) or Owen-scrambled Sobol (RenderSettings::sampler, sampling/rng.h
/// pixel_words); each stream has its own dimension counter.
class PixelStreamSampler final : public BdptSampler {
public:
    PixelStreamSampler(uint64_t seed, uint32_t pixel, uint32_t sample,
                       PixelSequence sequence = PixelSequence::independent)
        : m_key(seed_key(seed)), m_pixel(pixel), m_sample(sample), m_sequence(sequence) {}
    void start_stream(int index) override { m_stream = uint32_t(index) % 3u; }
    float next1d() override {
        uint32_t w[2];
        draw(w);
        return uint_to_unit_float(w[0]);
    }
    Vec2 next2d() override {
        uint32_t w[2];
        draw(w);
        return {uint_to_unit_float(w[0]), uint_to_unit_float(w[1])};
    }

private:
    /// Dimensions are computed k_ahead at a time per stream (pixel_words_lanes: one
    /// vectorised loop instead of a hash chain per draw); a draw reads its dimension's
    /// words from the stream's block, so the numbers are pixel_words' whatever the order
    /// of the streams' draws.
    static constexpr uint32_t k_ahead = 8;
    static_assert(k_ahead <= k_pixel_words_lanes, "pixel_words_lanes computes at most k_pixel_words_lanes");
    void draw(uint32_t* w) {
        const uint32_t s = m_stream, d = m_dim[s]++;
        uint32_t k = d - m_first[s];
        if (k >= m_have[s]) {  // unsigned: also d < m_first[s], which never happens
            const RngStream stream = RngStream(uint32_t(RngStream::bdpt_camera) + s);
            pixel_words_lanes(m_key, m_sequence, m_pixel, m_sample, d, k_ahead, stream, m_w0[s], m_w1[s], &m_seeds[s]);
            m_first[s] = d;
            m_have[s] = k_ahead;
            k = 0;
        }
        w[0] = m_w0[s][k];
        w[1] = m_w1[s][k];
    }
    Philox4x32Key m_key;
    uint32_t m_pixel, m_sample;
    PixelSequence m_sequence;
    uint32_t m_stream = 0;
    uint32_t m_dim[3] = {0, 0, 0};
    uint32_t m_first[3] = {0, 0, 0}, m_have[3] = {0, 0, 0};
    uint32_t m_w0[3][k_ahead], m_w1[3][k_ahead];
    SequenceSeeds m_seeds[3];
};

}  // namespace cmlt
