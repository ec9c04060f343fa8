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

/// sin(2π u) and cos(2π u) in double precision for u ∈ [0, 1] (the Metropolis kernels'
/// Box–Muller angles, sampling/rng.h): the same exact reduction to [−π/4, π/4], then the
/// Taylor series through x¹⁷ (sin) and x¹⁸ (cos), whose truncation (< 10⁻¹⁹) is below a
/// double's rounding — within a few ulps of libm's sincos (tests/cpp/math), inline
/// instead of a library call per pair of normals.
inline void sincos_turn_double(double u, double* s, double* c) {
    const double t = 4.0 * u;
    const double q = std::floor(t + 0.5);
    const double f = t - q;  // in [−1/2, 1/2], exact
    const double x = f * 1.57079632679489661923132169163975144;
    const double x2 = x * x;
    // Horner in x²: sin x = x (1 − x²/3! (1 − x²/(4·5) (1 − ...))), cos likewise
    double sp = 1.0 - x2 * (1.0 / (16.0 * 17.0));
    sp = 1.0 - x2 * (1.0 / (14.0 * 15.0)) * sp;
    sp = 1.0 - x2 * (1.0 / (12.0 * 13.0)) * sp;
    sp = 1.0 - x2 * (1.0 / (10.0 * 11.0)) * sp;
    sp = 1.0 - x2 * (1.0 / (8.0 * 9.0)) * sp;
    sp = 1.0 - x2 * (1.0 / (6.0 * 7.0)) * sp;
    sp = 1.0 - x2 * (1.0 / (4.0 * 5.0)) * sp;
    sp = 1.0 - x2 * (1.0 / (2.0 * 3.0)) * sp;
    double cp = 1.0 - x2 * (1.0 / (17.0 * 18.0));
    cp = 1.0 - x2 * (1.0 / (15.0 * 16.0)) * cp;
    cp = 1.0 - x2 * (1.0 / (13.0 * 14.0)) * cp;
    cp = 1.0 - x2 * (1.0 / (11.0 * 12.0)) * cp;
    cp = 1.0 - x2 * (1.0 / (9.0 * 10.0)) * cp;
    cp = 1.0 - x2 * (1.0 / (7.0 * 8.0)) * cp;
    cp = 1.0 - x2 * (1.0 / (5.0 * 6.0)) * cp;
    cp = 1.0 - x2 * (1.0 / (3.0 * 4.0)) * cp;
    cp = 1.0 - x2 * (1.0 / (1.0 * 2.0)) * cp;
    const double s0 = x * sp, c0 = cp;
    const int k = int(q) & 3;
    const double ss = (k & 1) ? c0 : s0, cc = (k & 1) ? s0 : c0;
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
