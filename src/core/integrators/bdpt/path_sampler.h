#pragma once
/// \file Independent numbers for BDPT's three streams (the BdptSampler interface,
/// base/sampler.h): the pixel samples of the bdpt integrator. The Metropolis integrators
/// drive the same code with their primary samples (BdptStreamAdapter, pssmlt_tracer.h).
#include "base/sampler.h"
#include "math/vec.h"
#include "sampling/rng.h"

#include <cstdint>

namespace cmlt {

/// Independent numbers of one pixel sample: Philox keyed by the seed, counter
/// (pixel, sample, dimension, RngStream::bdpt_camera + stream) (sampling/rng_domains.h);
/// each stream has its own dimension counter.
class PixelStreamSampler final : public BdptSampler {
public:
    PixelStreamSampler(uint64_t seed, uint32_t pixel, uint32_t sample)
        : m_key(seed_key(seed)), m_pixel(pixel), m_sample(sample) {}
    void start_stream(int index) override { m_stream = uint32_t(index) % 3u; }
    float next1d() override { return uint_to_unit_float(draw()[0]); }
    Vec2 next2d() override {
        Philox4x32Counter r = draw();
        return {uint_to_unit_float(r[0]), uint_to_unit_float(r[1])};
    }

private:
    Philox4x32Counter draw() {
        const RngStream stream = RngStream(uint32_t(RngStream::bdpt_camera) + m_stream);
        return philox4x32(pixel_counter(m_pixel, m_sample, m_dim[m_stream]++, stream), m_key);
    }
    Philox4x32Key m_key;
    uint32_t m_pixel, m_sample;
    uint32_t m_stream = 0;
    uint32_t m_dim[3] = {0, 0, 0};
};

}  // namespace cmlt
