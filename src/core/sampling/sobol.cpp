// Owen-scrambled Sobol points of many lanes at once; see sobol.h.
#include "sampling/sobol.h"

// Integer arithmetic only, so a wider instruction set gives the same bits faster: as
// philox.cpp, compiled also for AVX2 and AVX-512 with GCC on x86-64 (an ifunc).
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define CMLT_SOBOL_CLONES __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define CMLT_SOBOL_CLONES
#endif

namespace cmlt::sobol {

CMLT_SOBOL_CLONES
void seed_prefix_lanes(size_t n, const uint32_t* __restrict pixel, uint32_t sequence, uint32_t stream,
                       uint32_t* __restrict prefix) {
    for (size_t i = 0; i < n; ++i) prefix[i] = seed_prefix(pixel[i], sequence, stream);
}

CMLT_SOBOL_CLONES
void dimension_seeds_lanes(size_t n, const uint32_t* __restrict prefix, const uint32_t* __restrict dimension,
                           uint32_t key_hash, uint32_t* __restrict w0, uint32_t* __restrict w1) {
    for (size_t i = 0; i < n; ++i) dimension_seeds(prefix[i], key_hash, dimension[i], &w0[i], &w1[i]);
}

CMLT_SOBOL_CLONES
void scrambled_points_lanes(size_t n, uint32_t index, uint32_t* __restrict w0, uint32_t* __restrict w1) {
    for (size_t i = 0; i < n; ++i) {
        uint32_t w[2];
        scrambled_point(index, w0[i], w1[i], w);
        w0[i] = w[0];
        w1[i] = w[1];
    }
}

CMLT_SOBOL_CLONES
void dimension_points_lanes(size_t n, uint32_t prefix, uint32_t key_hash, uint32_t d0, uint32_t index,
                            uint32_t* __restrict w0, uint32_t* __restrict w1) {
    for (size_t i = 0; i < n; ++i) {
        uint32_t a, b, w[2];
        dimension_seeds(prefix, key_hash, d0 + uint32_t(i), &a, &b);
        scrambled_point(index, a, b, w);
        w0[i] = w[0];
        w1[i] = w[1];
    }
}

}  // namespace cmlt::sobol
