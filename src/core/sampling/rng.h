#pragma once
/// \file The renderer's random numbers: Philox-4x32 (philox.h) over the counter spaces
/// of the registry (rng_domains.h), turned into uniforms and normals.
///
///   PixelSampler   independent numbers of one pixel sample, dimension by dimension
///                  (the path tracer's Sampler, base/sampler.h);
///   CounterRng     a sequential stream keyed (seed, domain, id): the kernels' RNG
///                  (`uniform()`, `normal()`) of the Metropolis chains;
/// and the conversions every consumer shares (so the same bits give the same numbers
/// everywhere): 24 bits → float, 64 bits → double, Box–Muller, the torus wrap, and a
/// primary sample as the float a path routine reads.
#include "math/safe_math.h"
#include "math/sincos.h"
#include "math/vec.h"
#include "sampling/philox.h"
#include "sampling/rng_domains.h"
#include "sampling/sobol.h"

#include <cmath>
#include <cstdint>

namespace cmlt {

/// uint32 -> float in [0, 1) (top 24 bits; exactly representable, never 1).
inline float uint_to_unit_float(uint32_t v) { return float(v >> 8) * 0x1p-24f; }

/// 64 random bits → double in [0, 1) (53 bits; never 1).
inline double bits_to_unit(uint32_t hi, uint32_t lo) { return double(((uint64_t(hi) << 32) | lo) >> 11) * 0x1p-53; }

/// A primary sample u ∈ [0, 1) as the float a path routine reads: float(u) may round
/// up to 1, which becomes the largest float below 1 (math/safe_math.h's clamp_below_one).
inline float unit_float(double u) { return clamp_below_one(float(u)); }

/// Box–Muller's radius sqrt(-2 ln(1 - u1)) (u1 ∈ [0, 1)); its angle is 2 pi u2.
inline double box_muller_radius(double u1) { return std::sqrt(-2.0 * std::log(1.0 - u1)); }

/// Standard normal from two uniforms (Box–Muller, cosine branch; the angle's sine and
/// cosine from math/sincos.h's double-precision polynomials, not libm).
inline double box_muller(double u1, double u2) {
    double s, c;
    sincos_turn_double(u2, &s, &c);
    return box_muller_radius(u1) * c;
}

/// Both standard normals of one Box–Muller pair (independent): the cosine branch (the
/// value box_muller gives) and the sine branch.
inline void box_muller_pair(double u1, double u2, double* z_cos, double* z_sin) {
    const double r = box_muller_radius(u1);
    double s, c;
    sincos_turn_double(u2, &s, &c);
    *z_cos = r * c;
    *z_sin = r * s;
}

/// Map a real number onto [0, 1) (the unit torus of primary sample space). `v - floor(v)`
/// can round up to exactly 1.0 for tiny negative v (e.g. -1e-17), so that case is mapped
/// to 0; NaN and ±Inf also map to 0, so a primary sample is never outside [0, 1).
inline double wrap01(double v) {
    const double r = v - std::floor(v);
    return r < 1.0 ? r : 0.0;  // false for r == 1 and for NaN
}

/// The numbers of a pixel sample (RenderSettings::sampler): independent (Philox of the
/// sample's counter), a randomised low-discrepancy sequence over a pixel's samples
/// (Owen-scrambled Sobol, sampling/sobol.h), or such sequences in blocks: samples
/// [k B, (k + 1) B) of a pixel (B = k_sobol_block) are the first B points of block k's own
/// scrambled sequence, each block scrambled independently of the others. The blocks'
/// means are then independent estimates of the pixel (randomised QMC replicates), so
/// their spread is an unbiased estimate of the variance of the pixel's mean, which a
/// single sequence's samples do not give (their spread over-estimates it); each block
/// keeps the stratification of a B-point net. Either way a number is a pure function of
/// (seed, pixel, sample, dimension, stream), uniform on [0, 1).
enum class PixelSequence : uint8_t { independent, sobol, sobol_blocks };

/// Samples per block of PixelSequence::sobol_blocks (a power of two, so a block is a
/// net; README "Pixel samples" gives the measurements behind it).
inline constexpr uint32_t k_sobol_block = 8;

inline bool low_discrepancy(PixelSequence seq) { return seq != PixelSequence::independent; }

/// The sample word of the counters that seed the scrambles of `sample`'s sequence: one
/// sequence per pixel (k_sequence_seed_sample), or one per block of k_sobol_block
/// samples, counting down from it (rng_domains.h).
inline uint32_t sequence_seed_sample(PixelSequence seq, uint32_t sample) {
    return seq == PixelSequence::sobol_blocks ? k_sequence_seed_sample - sample / k_sobol_block
                                              : k_sequence_seed_sample;
}
/// The point of that sequence `sample` takes (before the index scramble).
inline uint32_t sequence_index(PixelSequence seq, uint32_t sample) {
    return seq == PixelSequence::sobol_blocks ? sample % k_sobol_block : sample;
}
/// Samples whose means are independent of each other's: the film's variance of the mean
/// comes from the spread of such blocks (Film::set_variance_block); 1 for independent
/// samples and for one sequence (whose spread over-estimates the variance).
inline uint32_t variance_block(PixelSequence seq) {
    return seq == PixelSequence::sobol_blocks ? k_sobol_block : 1u;
}

/// The parts of the scramble seeds that the dimensions of one pixel sample and stream
/// share (sobol.h seed_prefix, seed_key_hash), kept by a sampler from its first draw.
struct SequenceSeeds {
    uint32_t prefix = 0, key_hash = 0;
    bool ready = false;
};

/// `shared` made ready for (key, seq, pixel, sample, stream) if it is not yet.
inline void prepare_seeds(const Philox4x32Key& key, PixelSequence seq, uint32_t pixel, uint32_t sample,
                          RngStream stream, SequenceSeeds* shared) {
    if (shared->ready) return;
    shared->prefix = sobol::seed_prefix(pixel, sequence_seed_sample(seq, sample), uint32_t(stream));
    shared->key_hash = sobol::seed_key_hash(key[0], key[1]);
    shared->ready = true;
}

/// The two words of dimension d of pixel sample (pixel, sample, stream): the first two
/// of the Philox output of its counter, or its Owen-scrambled Sobol point (seeded by
/// sobol::scramble_seeds of the sequence's counter; `shared` keeps the parts every
/// dimension of the sample and stream has in common).
inline void pixel_words(const Philox4x32Key& key, PixelSequence seq, uint32_t pixel, uint32_t sample, uint32_t d,
                        RngStream stream, uint32_t* w, SequenceSeeds* shared) {
    if (low_discrepancy(seq)) {
        prepare_seeds(key, seq, pixel, sample, stream, shared);
        uint32_t a, b;
        sobol::dimension_seeds(shared->prefix, shared->key_hash, d, &a, &b);
        sobol::scrambled_point(sequence_index(seq, sample), a, b, w);
        return;
    }
    const Philox4x32Counter r = philox4x32(pixel_counter(pixel, sample, d, stream), key);
    w[0] = r[0];
    w[1] = r[1];
}
inline void pixel_words(const Philox4x32Key& key, PixelSequence seq, uint32_t pixel, uint32_t sample, uint32_t d,
                        RngStream stream, uint32_t* w) {
    SequenceSeeds shared;
    pixel_words(key, seq, pixel, sample, d, stream, w, &shared);
}

/// pixel_words of dimensions [d0, d0 + n) of one pixel sample and stream at once
/// (n <= k_pixel_words_lanes): dimension d0 + i's words into w0[i], w1[i], computed in
/// vectorised loops (sobol::dimension_points_lanes, or philox4x32_lanes) — the same
/// numbers as pixel_words one dimension at a time.
inline constexpr uint32_t k_pixel_words_lanes = 16;
inline void pixel_words_lanes(const Philox4x32Key& key, PixelSequence seq, uint32_t pixel, uint32_t sample,
                              uint32_t d0, uint32_t n, RngStream stream, uint32_t* w0, uint32_t* w1,
                              SequenceSeeds* shared) {
    if (low_discrepancy(seq)) {
        prepare_seeds(key, seq, pixel, sample, stream, shared);
        sobol::dimension_points_lanes(n, shared->prefix, shared->key_hash, d0, sequence_index(seq, sample), w0, w1);
        return;
    }
    uint32_t c0[k_pixel_words_lanes], c1[k_pixel_words_lanes], c2[k_pixel_words_lanes];
    for (uint32_t i = 0; i < n; ++i) {
        c0[i] = pixel;
        c1[i] = sample;
        c2[i] = d0 + i;
    }
    philox4x32_lanes(n, c0, c1, c2, uint32_t(stream), key, w0, w1);
}

/// Random numbers of one pixel sample: dimension d of (seed, pixel, sample, stream).
/// `get1d`/`get2d` consume dimensions in order; `set_dimension` jumps to a fixed
/// dimension so that e.g. each bounce owns a fixed dimension range. A dimension's
/// numbers are the first words (one for get1d, two for get2d) of the Philox output of
/// counter (pixel, sample, d, stream).
///
/// `prefetch` hands the sampler the words of a range of dimensions computed ahead
/// (philox4x32_lanes: many samples' dimensions at once, vectorised); reading them gives
/// the same numbers as calling Philox here.
class PixelSampler {
public:
    PixelSampler(uint64_t seed, uint32_t pixel, uint32_t sample, RngStream stream = RngStream::camera_path,
                 PixelSequence sequence = PixelSequence::independent)
        : m_key(seed_key(seed)), m_pixel(pixel), m_sample(sample), m_stream(stream), m_sequence(sequence) {}

    void set_dimension(uint32_t d) { m_dim = d; }
    uint32_t dimension() const { return m_dim; }

    float get1d() {
        uint32_t w[2];
        draw(w);
        return uint_to_unit_float(w[0]);
    }
    Vec2 get2d() {
        uint32_t w[2];
        draw(w);
        return {uint_to_unit_float(w[0]), uint_to_unit_float(w[1])};
    }

    /// Dimensions [first, first + n) read from `words` (words[2 (d - first)] and
    /// words[2 (d - first) + 1]: dimension d's two words as pixel_words gives them, for
    /// this sampler's sequence); `words` outlives their reads. Other dimensions are
    /// computed here.
    void prefetch(uint32_t first, uint32_t n, const uint32_t* words) {
        m_pre_first = first;
        m_pre_n = n;
        m_pre = words;
    }
    uint32_t pixel() const { return m_pixel; }
    uint32_t sample() const { return m_sample; }
    RngStream stream() const { return m_stream; }
    Philox4x32Key key() const { return m_key; }

private:
    void draw(uint32_t* w) {
        const uint32_t d = m_dim++;
        if (d - m_pre_first < m_pre_n) {  // unsigned: d >= first and d < first + n
            w[0] = m_pre[2 * (d - m_pre_first)];
            w[1] = m_pre[2 * (d - m_pre_first) + 1];
            return;
        }
        pixel_words(m_key, m_sequence, m_pixel, m_sample, d, m_stream, w, &m_seeds);
    }
    Philox4x32Key m_key;
    uint32_t m_pixel, m_sample;
    RngStream m_stream;
    PixelSequence m_sequence;
    SequenceSeeds m_seeds;
    uint32_t m_dim = 0;
    uint32_t m_pre_first = 0, m_pre_n = 0;
    const uint32_t* m_pre = nullptr;
};

/// Sequential counter-based generator with the kernels' RNG interface (uniform(),
/// normal()): draw k is a pure function of (seed, domain, id, k). Each Philox call gives
/// two uniforms (the second is kept for the next call); each Box–Muller pair two normals
/// (the sine branch is kept for the next normal(): one logarithm, square root and sincos
/// per two normals).
class CounterRng {
public:
    CounterRng(uint64_t seed, RngDomain domain, uint32_t id) : m_key(seed_key(seed)), m_domain(domain), m_id(id) {}

    double uniform() {
        if (m_has_spare) {
            m_has_spare = false;
            return m_spare;
        }
        const Philox4x32Counter r = philox4x32(metropolis_counter(RngTag::sequence, m_domain, m_id, m_draw++, 0), m_key);
        m_spare = bits_to_unit(r[2], r[3]);
        m_has_spare = true;
        return bits_to_unit(r[0], r[1]);
    }
    double normal() {
        if (m_has_spare_normal) {
            m_has_spare_normal = false;
            return m_spare_normal;
        }
        const double u1 = uniform();
        double z;
        box_muller_pair(u1, uniform(), &z, &m_spare_normal);
        m_has_spare_normal = true;
        return z;
    }

private:
    Philox4x32Key m_key;
    RngDomain m_domain;
    uint32_t m_id;
    uint64_t m_draw = 0;
    double m_spare = 0.0, m_spare_normal = 0.0;
    bool m_has_spare = false, m_has_spare_normal = false;
};

}  // namespace cmlt
