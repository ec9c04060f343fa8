#pragma once
/// \file Multiple importance sampling weights (Veach 1997, ch. 9).
#include <cmath>

namespace cmlt {

/// Power heuristic (beta = 2) for one sample from each of two strategies.
/// Infinite pdf_a (a Dirac strategy) gives 1; both zero gives 0.
inline float power_heuristic(float pdf_a, float pdf_b) {
    if (std::isinf(pdf_a)) return 1.f;
    if (std::isinf(pdf_b)) return 0.f;
    float a = pdf_a * pdf_a, b = pdf_b * pdf_b;
    if (!(a + b > 0.f)) return 0.f;
    return a / (a + b);
}

}  // namespace cmlt
