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
    void draw(uint32_t* w) {
        const RngStream stream = RngStream(uint32_t(RngStream::bdpt_camera) + m_stream);
        pixel_words(m_key, m_sequence, m_pixel, m_sample, m_dim[m_stream]++, stream, w, &m_seeds[m_stream]);
    }
    Philox4x32Key m_key;
    uint32_t m_pixel, m_sample;
    PixelSequence m_sequence;
    uint32_t m_stream = 0;
    uint32_t m_dim[3] = {0, 0, 0};
    SequenceSeeds m_seeds[3];
};

}  // namespace cmlt
