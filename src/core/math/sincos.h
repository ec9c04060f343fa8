#pragma once
/// \file Sine and cosine of the angles the samplers draw, as inline polynomials that the
/// compiler vectorises.
///
/// Why not libm: the SIMD lanes of the path batches (integrators/path/diffuse_lanes.h)
/// must compute the same floats as the per-lane routines (Bsdf::sample, the warps), and
/// no vector loop reproduces libm's sinf/cosf bit for bit, so the lanes called them one
/// lane at a time (8 % of pt's time on door_ajar). Every warp and microfacet sampler
/// reads its sine and cosine from here instead, so a scalar routine and a lane loop that
/// inline the same function agree exactly (with -ffp-contract=off, as the core is built).
///
/// The angles come as fractions of a turn or of a right angle, never as radians to be
/// reduced: the samplers' angles are 2π u (u ∈ [0, 1)) and π/4 · ratio (ratio ∈ [−1, 1]),
/// so the reduction to [−π/4, π/4] is exact in the sample's own units (t = 4u, the
/// nearest quadrant q, f = t − q: Sterbenz, no rounding). On [−π/4, π/4] the polynomials
/// are the Taylor series through x⁹ (sin) and x¹⁰ (cos), whose truncation (≤ 2·10⁻⁹) is
/// below float rounding: within 1·10⁻⁷ (2 ulp) of the exact values over a turn
/// (tests/cpp/math/test_math.cpp holds them to 3·10⁻⁷ against double precision).
#include "math/safe_math.h"
#include "math/vec.h"

#include <cmath>

#if defined(__GNUC__)
#define CMLT_SINCOS_INLINE inline __attribute__((always_inline))
#else
#define CMLT_SINCOS_INLINE inline
#endif

namespace cmlt {

/// sin(π/2 · f) and cos(π/2 · f) for f ∈ [−1/2, 1/2].
CMLT_SINCOS_INLINE void sincos_quarter(float f, float* s, float* c) {
    const float x = f * k_pi_over_2;
    const float x2 = x * x;
    // (−1)^k / (2k+1)! and (−1)^k / (2k)!
    const float sp = -1.66666666666666667e-1f +
                     x2 * (8.33333333333333333e-3f + x2 * (-1.98412698412698413e-4f + x2 * 2.75573192239858907e-6f));
    const float cp = -0.5f + x2 * (4.16666666666666667e-2f +
                                   x2 * (-1.38888888888888889e-3f +
                                         x2 * (2.48015873015873016e-5f + x2 * -2.75573192239858907e-7f)));
    *s = x + x * (x2 * sp);
    *c = 1.f + x2 * cp;
}

/// sin(2π u) and cos(2π u) for u ∈ [0, 1] (or any |u| below 2²¹, reduced exactly).
CMLT_SINCOS_INLINE void sincos_turn(float u, float* s, float* c) {
    const float t = 4.f * u;
    const float q = std::floor(t + 0.5f);  // the nearest quadrant
    const float f = t - q;                 // in [−1/2, 1/2], exact
    float s0, c0;
    sincos_quarter(f, &s0, &c0);
    // rotate by q right angles: (s, c) → (c, −s) per quadrant
    const int k = int(q) & 3;
    const float ss = (k & 1) ? c0 : s0, cc = (k & 1) ? s0 : c0;
    *s = (k & 2) ? -ss : ss;
    *c = ((k + 1) & 2) ? -cc : cc;
}

/// The concentric map of the unit square to the unit disk (Shirley & Chiu 1997) without
/// branches, for the lanes and the warps alike (square_to_uniform_disk_concentric).
CMLT_SINCOS_INLINE Vec2 concentric_disk(float ux, float uy) {
    const float x = 2.f * ux - 1.f, y = 2.f * uy - 1.f;
    const bool wide = std::fabs(x) > std::fabs(y);
    const float r = wide ? x : y, other = wide ? y : x;
    // θ = π/4 · y/x where |x| > |y|, else π/2 − π/4 · x/y: cos and sin swap
    const float f = r != 0.f ? 0.5f * (other / r) : 0.f;
    float s, c;
    sincos_quarter(f, &s, &c);
    return wide ? Vec2(r * c, r * s) : Vec2(r * s, r * c);
}

}  // namespace cmlt
