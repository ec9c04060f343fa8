#pragma once
/// \file Safe maths: no NaN from rounding just outside a function's domain.
#include <algorithm>
#include <cmath>

namespace cmlt {

constexpr float k_pi = 3.14159265358979323846f;
constexpr float k_inv_pi = 0.31830988618379067154f;
constexpr float k_inv_2pi = 0.15915494309189533577f;
constexpr float k_inv_4pi = 0.07957747154594766788f;
constexpr float k_pi_over_2 = 1.57079632679489661923f;
constexpr float k_pi_over_4 = 0.78539816339744830961f;
/// Largest float below 1: uniform samples are clamped to [0, k_one_minus_eps].
constexpr float k_one_minus_eps = 0x1.fffffep-1f;

/// f, or k_one_minus_eps where f ≥ 1 (rounding took a sample in [0, 1) to 1): the one
/// clamp of a uniform to [0, 1) (sampling/rng.h's unit_float for doubles).
inline float clamp_below_one(float f) { return f < 1.f ? f : k_one_minus_eps; }

inline float safe_sqrt(float x) { return std::sqrt(std::max(0.f, x)); }
inline double safe_sqrt(double x) { return std::sqrt(std::max(0.0, x)); }
inline float safe_acos(float x) { return std::acos(std::clamp(x, -1.f, 1.f)); }
inline float safe_asin(float x) { return std::asin(std::clamp(x, -1.f, 1.f)); }
inline float sqr(float x) { return x * x; }
inline float clamp01(float x) { return std::clamp(x, 0.f, 1.f); }
inline float radians(float deg) { return deg * (k_pi / 180.f); }

}  // namespace cmlt
