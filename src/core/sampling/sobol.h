#pragma once
/// \file Owen-scrambled Sobol points, two dimensions at a time: the pixel samples'
/// low-discrepancy sequence (RenderSettings::sampler = "sobol"; PixelSampler and
/// PixelStreamSampler read it instead of independent Philox numbers).
///
/// Each dimension of a pixel sample (a `get2d`: two numbers) takes point j of the first
/// two Sobol dimensions. Those form a (0,2)-sequence in base 2: every aligned block of
/// 2^m consecutive points is a (0,m,2)-net, one point in each of the 2^m elementary
/// intervals of every shape (2^a × 2^(m−a) cells). Two random scrambles, seeded per
/// (seed, pixel, sequence, dimension, stream) by scramble_seeds, make it a randomised
/// quasi-Monte Carlo sequence:
///
///   * the sample index is shuffled, j = scramble(i): a nested uniform scramble of the
///     index's bits, whose top bits depend only on the top bits of i. The first 2^m
///     samples of a pixel (or any aligned block of 2^m sample indices, such as those
///     from the direct pass's base) go to an aligned block of 2^m points, so every
///     power-of-two prefix keeps the net property. Shuffled independently per dimension,
///     the dimensions are stratified each on its own and do not correlate with each
///     other (padding);
///   * each coordinate is Owen-scrambled (a nested uniform scramble of its bits: at
///     every node of the binary tree of intervals the two halves are swapped or not at
///     random). Every point is then uniform on [0,1)², so every estimate stays unbiased,
///     and the nets stay nets.
///
/// The scrambles are the hash-based kind: reverse the bits, apply a permutation in
/// which each bit is flipped by a function of the bits below it only (additions,
/// multiplications by odd numbers, x ^= x·even), reverse back — Burley (2020), with the
/// hash constants of Vegdahl (2021). Progressive: the pass loop does not need to know
/// the sample count ahead, so time budgets and target errors work as with independent
/// numbers.
#include <cstddef>
#include <cstdint>

namespace cmlt::sobol {

inline uint32_t reverse_bits(uint32_t x) {
    x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
    x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
    x = ((x >> 4) & 0x0F0F0F0Fu) | ((x & 0x0F0F0F0Fu) << 4);
    return __builtin_bswap32(x);
}

/// A random permutation of 32-bit words in which bit k of the result is bit k of `x`
/// flipped by a function of bits 0..k−1 and the seed (applied to reversed bits, a
/// nested uniform scramble).
inline uint32_t lower_bits_hash(uint32_t x, uint32_t seed) {
    x ^= x * 0x3d20adeau;
    x += seed;
    x *= (seed >> 16) | 1u;
    x ^= x * 0x05526c56u;
    x ^= x * 0x53a22864u;
    return x;
}

/// Nested uniform (Owen) scramble of the bits of `x`, most significant first.
inline uint32_t nested_uniform_scramble(uint32_t x, uint32_t seed) {
    return reverse_bits(lower_bits_hash(reverse_bits(x), seed));
}

/// The superset transform of a word's bits over GF(2): bit i of the result is the XOR
/// of the bits k of `j` whose positions contain i's (k & i == i), in five shift steps.
inline uint32_t superset_xor(uint32_t j) {
    j ^= (j >> 1) & 0x55555555u;
    j ^= (j >> 2) & 0x33333333u;
    j ^= (j >> 4) & 0x0F0F0F0Fu;
    j ^= (j >> 8) & 0x00FF00FFu;
    j ^= (j >> 16) & 0x0000FFFFu;
    return j;
}

/// Sobol dimension 1 of point j (primitive polynomial x + 1: direction numbers
/// v_0 = 2^31, v_k = v_(k−1) xor v_(k−1)/2), as 32 bits of [0, 1). v_k is row k of
/// Pascal's triangle mod 2 from the top bit down, and C(k, i) is odd exactly when the
/// bits of i are among those of k (Lucas), so the point's bit i from the top is the XOR
/// of j's bits k ⊇ i: reverse_bits(superset_xor(j)).
inline uint32_t sobol1(uint32_t j) { return reverse_bits(superset_xor(j)); }

/// lowbias32 (Wellons' integer hash search): a bijection of 32-bit words whose output bits
/// each flip with probability ~1/2 when one input bit does.
inline uint32_t mix32(uint32_t x) {
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
}

/// scramble_seeds (below) in parts: the key's (one word per render), the sample's for
/// one stream (shared by its dimensions; a sampler computes both once), then the
/// dimension's.
inline uint32_t seed_key_hash(uint32_t key0, uint32_t key1) { return mix32(mix32(key0 ^ 0xbb67ae85u) ^ key1); }
inline uint32_t seed_prefix(uint32_t pixel, uint32_t sequence, uint32_t stream) {
    return mix32(mix32(mix32(pixel ^ 0x6a09e667u) ^ sequence) ^ stream);
}
inline void dimension_seeds(uint32_t prefix, uint32_t key_hash, uint32_t dimension, uint32_t* seed_a,
                            uint32_t* seed_b) {
    const uint32_t a = mix32(mix32(prefix ^ dimension) ^ key_hash);
    *seed_a = a;
    *seed_b = mix32(a ^ 0x9e3779b9u);
}

/// The two seed words of one dimension's scrambles, a hash of (key, pixel, sequence,
/// dimension, stream): the pixel, sequence, stream and dimension words folded into a
/// 32-bit state and mixed in turn, then the key's hash (its two words mixed). Philox-10,
/// which seeded them before, cost 8 % of a path-traced frame; the seeds need no more
/// than well-mixed bits, which this gives with fewer multiplies, and a sampler reuses
/// all but the last three mixes across its dimensions. The key goes last because a word
/// folded in by XOR ties two states that differ by that word's difference: with the key
/// first, seed s's pixel p hashed as seed s′'s pixel p ^ s ^ s′ in every dimension —
/// renders of different seeds were the same paths on permuted pixels. Folded in last,
/// two keys meet only where two pseudo-random states happen to differ by the keys'
/// difference: single words at random places, as any two 32-bit hashes meet
/// (tests/cpp/sampling/test_sobol.cpp counts them). The arguments are a pixel-sample
/// counter's words (rng_domains.h pixel_counter, with the sequence's seed sample) and
/// the key's (seed_key).
inline void scramble_seeds(uint32_t key0, uint32_t key1, uint32_t pixel, uint32_t sequence, uint32_t dimension,
                           uint32_t stream, uint32_t* seed_a, uint32_t* seed_b) {
    dimension_seeds(seed_prefix(pixel, sequence, stream), seed_key_hash(key0, key1), dimension, seed_a, seed_b);
}

/// seed_prefix of n lanes: pixel[i], one sequence and stream, into prefix[i] (the loop
/// vectorises; sobol.cpp).
void seed_prefix_lanes(size_t n, const uint32_t* pixel, uint32_t sequence, uint32_t stream, uint32_t* prefix);
/// dimension_seeds of n lanes: prefix[i] (seed_prefix), dimension[i], one key_hash
/// (seed_key_hash); the seeds into w0[i], w1[i] — scramble_seeds of each lane, with the
/// parts every dimension of a pixel sample shares computed once per sample.
void dimension_seeds_lanes(size_t n, const uint32_t* prefix, const uint32_t* dimension, uint32_t key_hash,
                           uint32_t* w0, uint32_t* w1);

/// The third seed of a dimension from its two seed words (an integer hash: its bits look
/// independent of the other two).
inline uint32_t third_seed(uint32_t seed_a, uint32_t seed_b) {
    return mix32(seed_a ^ ((seed_b << 16) | (seed_b >> 16)));
}

/// The two 32-bit words of sample `index` of one dimension, from the dimension's two
/// seed words: seed_a shuffles the index, seed_b scrambles the first coordinate,
/// third_seed(seed_a, seed_b) the second. (The reversals of the scrambles and of the
/// Sobol dimensions cancel in pairs; what is left is the same function.)
inline void scrambled_point(uint32_t index, uint32_t seed_a, uint32_t seed_b, uint32_t* w) {
    const uint32_t j = reverse_bits(lower_bits_hash(reverse_bits(index), seed_a));  // shuffled index
    // Sobol dimension 0 is reverse_bits(j) (van der Corput), so its scramble is
    // reverse(hash(j)); dimension 1's is reverse(hash(superset_xor(j)))
    w[0] = reverse_bits(lower_bits_hash(j, seed_b));
    w[1] = reverse_bits(lower_bits_hash(superset_xor(j), third_seed(seed_a, seed_b)));
}

/// scrambled_point of one sample index for n lanes (dimensions or pixels) at once: the
/// seeds in w0[i], w1[i], which receive the point (the loop vectorises; sobol.cpp).
void scrambled_points_lanes(size_t n, uint32_t index, uint32_t* w0, uint32_t* w1);

/// The points of sample `index` of dimensions d0 .. d0 + n - 1 of one pixel sample and
/// stream (its seed_prefix and the key's seed_key_hash) into w0[i], w1[i]: dimension_seeds
/// then scrambled_point, the dimensions in lanes (sobol.cpp).
void dimension_points_lanes(size_t n, uint32_t prefix, uint32_t key_hash, uint32_t d0, uint32_t index,
                            uint32_t* w0, uint32_t* w1);

}  // namespace cmlt::sobol
