#pragma once
/// \file Lambertian (ideal diffuse) reflection, two-sided, in the local shading frame.
///
/// Conventions (all BSDFs): directions are local (z = shading normal), unit length, and
/// point away from the surface; pdfs are per solid angle.
#include "materials/bsdf_sample.h"
#include "sampling/warp.h"

#include <cmath>

namespace cmlt {

class LambertianBsdf {
public:
    explicit LambertianBsdf(const Spectrum& reflectance) : m_r(reflectance) {}

    Spectrum eval(const Vec3& wo, const Vec3& wi) const {
        if (wo.z * wi.z <= 0.f) return Spectrum(0.f);
        return m_r * k_inv_pi;
    }
    float pdf(const Vec3& wo, const Vec3& wi) const {
        if (wo.z * wi.z <= 0.f) return 0.f;
        return std::fabs(wi.z) * k_inv_pi;
    }
    BsdfSample sample(const Vec3& wo, const Vec2& u2, float /*u1*/) const {
        BsdfSample s;
        if (wo.z == 0.f) return s;
        Vec3 wi = square_to_cosine_hemisphere(u2);
        if (wo.z < 0.f) wi.z = -wi.z;
        s.pdf = std::fabs(wi.z) * k_inv_pi;
        if (!(s.pdf > 0.f)) return BsdfSample();
        s.wi = wi;
        s.f = m_r * k_inv_pi;
        return s;
    }
    bool is_delta() const { return false; }
    Spectrum albedo() const { return m_r; }

private:
    Spectrum m_r;
};

}  // namespace cmlt
