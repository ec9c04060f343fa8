#pragma once
/// \file Flush-to-zero / denormals-are-zero for render threads.
///
/// Embree warns (and runs slower) with denormals enabled. Every render task sets
/// the mode at its start, so all threads, including the calling one, compute
/// bit-identical results.
#include <xmmintrin.h>
#include <pmmintrin.h>

namespace cmlt {

inline void set_ftz_daz() {
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
}

/// Sets FTZ/DAZ for a scope and restores the previous MXCSR afterwards.
class ScopedFtzDaz {
public:
    ScopedFtzDaz() : m_saved(_mm_getcsr()) { set_ftz_daz(); }
    ~ScopedFtzDaz() { _mm_setcsr(m_saved); }
    ScopedFtzDaz(const ScopedFtzDaz&) = delete;
    ScopedFtzDaz& operator=(const ScopedFtzDaz&) = delete;

private:
    unsigned int m_saved;
};

}  // namespace cmlt
