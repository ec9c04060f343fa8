#pragma once
/// \file Independent numbers for BDPT's three streams (the BdptSampler interface,
/// base/sampler.h): the pixel samples of the bdpt integrator. The Metropolis integrators
/// drive the same code with their primary samples (BdptStreamAdapter, pssmlt_tracer.h).
#include "base/sampler.h"
#include "math/vec.h"
#include "sampling/rng.h"

#include <cstdint>
#include <vector>

namespace cmlt {

/// The numbers of one pixel sample: counter (pixel, sample, dimension,
/// RngStream::bdpt_camera + stream) (sampling/rng_domains.h), independent (Philox keyed
/// by the seed) or Owen-scrambled Sobol (RenderSettings::sampler, sampling/rng.h
/// pixel_words); each stream has its own dimension counter. A stream's first dimensions
/// may be handed over computed (prefetch: PixelStreamPrefetch does it for a tile's
/// samples at once); the others are computed when read.
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
    /// Dimensions [0, n) of stream `index` read from w0[d], w1[d] (the two words
    /// pixel_words gives dimension d), which outlive their reads.
    void prefetch(int index, uint32_t n, const uint32_t* w0, const uint32_t* w1) {
        m_pre_n[index] = n;
        m_pre_w0[index] = w0;
        m_pre_w1[index] = w1;
    }

private:
    void draw(uint32_t* w) {
        const uint32_t d = m_dim[m_stream]++;
        if (d < m_pre_n[m_stream]) {
            w[0] = m_pre_w0[m_stream][d];
            w[1] = m_pre_w1[m_stream][d];
            return;
        }
        const RngStream stream = RngStream(uint32_t(RngStream::bdpt_camera) + m_stream);
        pixel_words(m_key, m_sequence, m_pixel, m_sample, d, stream, w);
    }
    Philox4x32Key m_key;
    uint32_t m_pixel, m_sample;
    PixelSequence m_sequence;
    uint32_t m_stream = 0;
    uint32_t m_dim[3] = {0, 0, 0};
    uint32_t m_pre_n[3] = {0, 0, 0};
    const uint32_t* m_pre_w0[3] = {nullptr, nullptr, nullptr};
    const uint32_t* m_pre_w1[3] = {nullptr, nullptr, nullptr};
};

/// The first dimensions of every stream of many pixel samples of one sample index (a
/// tile's pixels in one pass), computed at once: Philox over all their counters
/// (philox4x32_lanes) and, with a Sobol sequence, the scrambled points
/// (sobol::scrambled_points_lanes) — loops that vectorise. Computed one at a time, a
/// BDPT sample's numbers were 15 % of the integrator's instructions (a sample reads 13-21
/// dimensions over its three streams on the test shots; tests/bench/results/profile.md).
class PixelStreamPrefetch {
public:
    /// Dimensions prefetched per stream (camera, light, connection): a little above what
    /// an average sample reads; the rest are computed when read.
    static constexpr uint32_t k_dims[3] = {8, 8, 4};

    /// The words of sample `sample` of the n pixels keyed pixels[0..n).
    void compute(uint64_t seed, PixelSequence sequence, const uint32_t* pixels, size_t n, uint32_t sample) {
        const bool sobol = low_discrepancy(sequence);
        const uint32_t c1 = sobol ? sequence_seed_sample(sequence, sample) : sample;
        for (int s = 0; s < 3; ++s) {
            const uint32_t K = k_dims[s];
            const size_t m = n * K;
            m_c0.resize(m);
            m_c1.resize(m);
            m_c2.resize(m);
            m_w0[s].resize(m);
            m_w1[s].resize(m);
            for (size_t i = 0, j = 0; i < n; ++i)
                for (uint32_t k = 0; k < K; ++k, ++j) {
                    m_c0[j] = pixels[i];
                    m_c1[j] = c1;
                    m_c2[j] = k;
                }
            const RngStream stream = RngStream(uint32_t(RngStream::bdpt_camera) + uint32_t(s));
            philox4x32_lanes(m, m_c0.data(), m_c1.data(), m_c2.data(), uint32_t(stream), seed_key(seed),
                             m_w0[s].data(), m_w1[s].data());
            if (sobol) sobol::scrambled_points_lanes(m, sequence_index(sequence, sample), m_w0[s].data(), m_w1[s].data());
        }
    }
    /// Hands pixel i's words (of the last compute) to its sampler.
    void apply(size_t i, PixelStreamSampler& sampler) const {
        for (int s = 0; s < 3; ++s)
            sampler.prefetch(s, k_dims[s], m_w0[s].data() + i * k_dims[s], m_w1[s].data() + i * k_dims[s]);
    }

private:
    std::vector<uint32_t> m_c0, m_c1, m_c2;
    std::vector<uint32_t> m_w0[3], m_w1[3];
};

}  // namespace cmlt
