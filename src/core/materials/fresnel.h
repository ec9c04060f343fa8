#pragma once
/// \file Fresnel terms and specular geometry (reflect / refract) in the local shading frame.
///
/// Conventions (see materials/preview_surface.h): directions point away from the surface,
/// `eta` is the interior IOR over the exterior IOR, the normal is +z unless passed explicitly.
/// Everything here is header-only and NaN-free for unit inputs, including cos = 0 and eta = 1.
#include "math/safe_math.h"
#include "math/vec.h"

#include <cmath>

namespace cmlt {

/// Mirror `wo` about the normal `n` (both unit; the result points to n's side of wo).
inline Vec3 reflect(const Vec3& wo, const Vec3& n) { return -wo + n * (2.f * dot(wo, n)); }

/// Refract `wi` (pointing away from the surface) through the interface with normal `n`.
/// `eta` is the IOR behind `n` over the IOR in front of it (interior over exterior when
/// `n` points outwards). If `wi` is behind `n` (dot(wi, n) < 0) the relative IOR becomes
/// 1/eta. On success writes the transmitted direction `wt` (unit, on the other side) and
/// `etap`, the relative IOR actually crossed (eta_t / eta_i). Returns false on total
/// internal reflection. Same contract as pbrt-v4 `Refract`.
inline bool refract(const Vec3& wi, Vec3 n, float eta, float* etap, Vec3* wt) {
    float cos_i = dot(n, wi);
    if (cos_i < 0.f) {
        eta = 1.f / eta;
        cos_i = -cos_i;
        n = -n;
    }
    float sin2_i = std::max(0.f, 1.f - cos_i * cos_i);
    float sin2_t = sin2_i / (eta * eta);
    if (sin2_t >= 1.f) return false;
    float cos_t = safe_sqrt(1.f - sin2_t);
    *wt = -wi / eta + n * (cos_i / eta - cos_t);
    *etap = eta;
    return true;
}

/// Exact unpolarised Fresnel reflectance of a dielectric interface.
/// `cos_theta_i` is signed: negative means the incident direction is on the inside, in
/// which case the relative IOR is inverted. Returns 1 under total internal reflection and
/// exactly 0 for eta == 1 (no interface; avoids 0/0 at grazing incidence).
inline float fresnel_dielectric(float cos_theta_i, float eta) {
    if (eta == 1.f) return 0.f;
    cos_theta_i = std::clamp(cos_theta_i, -1.f, 1.f);
    if (cos_theta_i < 0.f) {
        eta = 1.f / eta;
        cos_theta_i = -cos_theta_i;
    }
    float sin2_i = 1.f - cos_theta_i * cos_theta_i;
    float sin2_t = sin2_i / (eta * eta);
    if (sin2_t >= 1.f) return 1.f;
    float cos_t = safe_sqrt(1.f - sin2_t);
    // eta != 1 here, so the denominators are > 0 even at cos_i = 0 (cos_t > 0 for eta > 1).
    float r_parl = (eta * cos_theta_i - cos_t) / (eta * cos_theta_i + cos_t);
    float r_perp = (cos_theta_i - eta * cos_t) / (cos_theta_i + eta * cos_t);
    return 0.5f * (r_parl * r_parl + r_perp * r_perp);
}

/// Normal-incidence reflectance of a dielectric with relative IOR `eta`:
/// ((eta - 1) / (eta + 1))^2 (0.04 for eta = 1.5).
inline float schlick_f0_from_ior(float eta) { return sqr((eta - 1.f) / (eta + 1.f)); }

/// Schlick's weight (1 - cos)^5, with cos clamped to [0, 1].
inline float schlick_weight(float cos_theta) {
    float m = clamp01(1.f - cos_theta);
    float m2 = m * m;
    return m2 * m2 * m;
}

/// Schlick's approximation F0 + (F90 - F0)(1 - cos)^5 (scalar).
inline float fresnel_schlick(float f0, float f90, float cos_theta) {
    return f0 + (f90 - f0) * schlick_weight(cos_theta);
}

/// Schlick's approximation per channel, with a scalar F90.
inline Spectrum fresnel_schlick(const Spectrum& f0, float f90, float cos_theta) {
    float w = schlick_weight(cos_theta);
    return f0 + (Spectrum(f90) - f0) * w;
}

}  // namespace cmlt
