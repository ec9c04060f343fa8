#pragma once
/// \file Philox-4x32-10 (Salmon et al. 2011, "Parallel random numbers: as easy as 1, 2,
/// 3"), the counter-based generator behind the renderer's random numbers (the Sobol
/// sequences' scramble seeds are a cheaper hash of the same counters: sobol.h).
///
/// A value is a pure function of (key, counter): there is no sequential state, so results
/// do not depend on thread count or scheduling. The key is the shot seed (seed_key); how
/// the counter is laid out for each consumer is registered in rng_domains.h.
#include <array>
#include <cstddef>
#include <cstdint>

namespace cmlt {

using Philox4x32Counter = std::array<uint32_t, 4>;
using Philox4x32Key = std::array<uint32_t, 2>;

/// Philox-4x32 with 10 rounds.
inline Philox4x32Counter philox4x32(Philox4x32Counter c, Philox4x32Key k) {
    constexpr uint32_t M0 = 0xD2511F53u, M1 = 0xCD9E8D57u;
    constexpr uint32_t W0 = 0x9E3779B9u, W1 = 0xBB67AE85u;
    for (int round = 0; round < 10; ++round) {
        uint64_t p0 = uint64_t(M0) * c[0];
        uint64_t p1 = uint64_t(M1) * c[2];
        uint32_t hi0 = uint32_t(p0 >> 32), lo0 = uint32_t(p0);
        uint32_t hi1 = uint32_t(p1 >> 32), lo1 = uint32_t(p1);
        c = {hi1 ^ c[1] ^ k[0], lo1, hi0 ^ c[3] ^ k[1], lo0};
        k[0] += W0;
        k[1] += W1;
    }
    return c;
}

/// Philox-4x32-10 of n counters (c0[i], c1[i], c2[i], c3) under one key: the first two
/// words of each output in w0[i], w1[i] (philox4x32's bits). A plain loop over the lanes
/// that the compiler vectorises (SSE2 and up: 2–2.7x fewer cycles per counter than one
/// call at a time on this project's machines; where the CPU has AVX2 or AVX-512 a clone
/// compiled for it is chosen at load time, the same bits); philox.cpp.
void philox4x32_lanes(size_t n, const uint32_t* c0, const uint32_t* c1, const uint32_t* c2, uint32_t c3,
                      Philox4x32Key key, uint32_t* w0, uint32_t* w1);

/// The Philox key of a 64-bit seed: its low and high words.
inline Philox4x32Key seed_key(uint64_t seed) { return {uint32_t(seed), uint32_t(seed >> 32)}; }

}  // namespace cmlt
