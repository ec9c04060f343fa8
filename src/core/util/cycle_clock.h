#pragma once
/// \file A cheap clock for timing short calls (BVH queries): the CPU's time-stamp
/// counter where there is one (a few nanoseconds per read, against ~20 ns for
/// steady_clock through the vDSO and a ray query of a few hundred), steady_clock
/// elsewhere. Ticks become seconds through a rate measured over a whole render
/// (CycleRate), so no fixed frequency is assumed.
#include <chrono>
#include <cstdint>

#if defined(__x86_64__) || defined(_M_X64) || defined(__i386__)
#include <x86intrin.h>
#define CMLT_HAVE_RDTSC 1
#endif

namespace cmlt {

inline uint64_t cycle_now() {
#ifdef CMLT_HAVE_RDTSC
    return __rdtsc();
#else
    return uint64_t(std::chrono::steady_clock::now().time_since_epoch().count());
#endif
}

/// Ticks per second, measured between construction and `per_second()`.
class CycleRate {
public:
    CycleRate() : m_t0(std::chrono::steady_clock::now()), m_c0(cycle_now()) {}
    double per_second() const {
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - m_t0).count();
        const uint64_t c = cycle_now() - m_c0;
        return s > 0.0 && c > 0 ? double(c) / s : 1e9;
    }

private:
    std::chrono::steady_clock::time_point m_t0;
    uint64_t m_c0;
};

}  // namespace cmlt
