// Philox over many counters at once; see philox.h.
#include "sampling/philox.h"

// The lanes are integer arithmetic, so a wider instruction set gives the same bits
// faster: with GCC on x86-64 the function is also compiled for AVX2 and AVX-512 (8 and
// 16 lanes per 32 x 32 -> 64 bit multiply instead of SSE2's 4) and the loader picks the
// widest the CPU runs (an ifunc). The rest of the core stays at the portable baseline.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define CMLT_PHILOX_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define CMLT_PHILOX_CLONES
#endif

namespace cmlt {

CMLT_PHILOX_CLONES
void philox4x32_lanes(size_t n, const uint32_t* __restrict c0, const uint32_t* __restrict c1,
                      const uint32_t* __restrict c2, uint32_t c3, Philox4x32Key key, uint32_t* __restrict w0,
                      uint32_t* __restrict w1) {
    constexpr uint32_t M0 = 0xD2511F53u, M1 = 0xCD9E8D57u;
    constexpr uint32_t W0 = 0x9E3779B9u, W1 = 0xBB67AE85u;
    // The rounds of philox4x32 on one lane's words; lanes are independent, so the loop
    // over them vectorises (the 32 x 32 -> 64 bit products become pmuludq).
    for (size_t i = 0; i < n; ++i) {
        uint32_t a = c0[i], b = c1[i], c = c2[i], d = c3;
        uint32_t k0 = key[0], k1 = key[1];
#pragma GCC unroll 10
        for (int round = 0; round < 10; ++round) {
            const uint64_t p0 = uint64_t(M0) * a;
            const uint64_t p1 = uint64_t(M1) * c;
            a = uint32_t(p1 >> 32) ^ b ^ k0;
            b = uint32_t(p1);
            c = uint32_t(p0 >> 32) ^ d ^ k1;
            d = uint32_t(p0);
            k0 += W0;
            k1 += W1;
        }
        w0[i] = a;
        w1[i] = b;
    }
}

}  // namespace cmlt
