#pragma once
/// \file Isotropic GGX (Trowbridge–Reitz) microfacet distribution with visible-normal sampling.
///
/// References:
///  - Walter et al. 2007, "Microfacet Models for Refraction through Rough Surfaces" (D, and the
///    generalised half vector for transmission).
///  - Heitz 2014, "Understanding the Masking-Shadowing Function in Microfacet-Based BRDFs"
///    (Smith Lambda, height-correlated G2).
///  - Heitz 2018, "Sampling the GGX Distribution of Visible Normals" (JCGT 7(4)) —
///    `sample_visible` is Listing 1 of that paper.
///
/// Local frame: z is the macro normal, micro normals `wm` have wm.z > 0. Directions may be
/// on either side (w.z < 0); Lambda and G1 only depend on |w.z|.
///
/// Masking–shadowing is Smith **height-correlated** G2 = 1 / (1 + Lambda(wo) + Lambda(wi))
/// (Heitz 2014 eq. 99), used for reflection and (as in pbrt-v4) for transmission.
/// All quotients that appear in BSDFs are written in forms without 1/cos so that they stay
/// finite at grazing angles, e.g. G1(w)/|cos w| = 2 / (|cos| + sqrt(a^2 + (1 - a^2) cos^2)).
#include "math/safe_math.h"
#include "math/sincos.h"
#include "math/vec.h"

#include <cmath>

namespace cmlt {

/// Below this alpha a GGX lobe is treated as a Dirac delta (perfect mirror / smooth
/// dielectric). With alpha = roughness^2 this is roughness < ~0.0316. At alpha = 1e-3 the
/// GGX peak is D(n) = 1/(pi alpha^2) ~ 3e5, still comfortably finite in float.
constexpr float k_ggx_delta_alpha = 1e-3f;

/// UsdPreviewSurface convention: alpha = roughness^2 (roughness clamped to [0, 1]).
inline float ggx_alpha_from_roughness(float roughness) { return sqr(clamp01(roughness)); }

/// Isotropic GGX distribution with parameter alpha (>= k_ggx_delta_alpha for non-delta use).
class GgxDistribution {
public:
    explicit GgxDistribution(float alpha) : m_alpha(alpha), m_alpha2(alpha * alpha) {}

    float alpha() const { return m_alpha; }
    bool is_delta() const { return m_alpha < k_ggx_delta_alpha; }

    /// Normal distribution D(wm), a density per solid angle of wm normalised so that the
    /// integral of D(wm) cos(theta_m) over the hemisphere is 1. Zero for wm.z <= 0.
    /// Written as a^2 / (pi (x^2 + y^2 + a^2 z^2)^2), which has no tan/cos^4 terms.
    float d(const Vec3& wm) const {
        if (wm.z <= 0.f) return 0.f;
        float t = wm.x * wm.x + wm.y * wm.y + m_alpha2 * wm.z * wm.z;
        if (!(t > 0.f)) return 0.f;
        return m_alpha2 / (k_pi * t * t);
    }

    /// sqrt(a^2 + (1 - a^2) cos^2), the recurring term of the Smith GGX masking function.
    float smith_s(const Vec3& w) const {
        float c2 = w.z * w.z;
        return std::sqrt(m_alpha2 + (1.f - m_alpha2) * c2);
    }

    /// Smith Lambda(w) = (sqrt(1 + a^2 tan^2) - 1) / 2. Infinite at the horizon.
    float lambda(const Vec3& w) const {
        float c = std::fabs(w.z);
        if (c == 0.f) return INFINITY;
        return 0.5f * (smith_s(w) - c) / c;
    }

    /// Smith masking G1(w) = 2|cos| / (|cos| + s(w)); 0 at the horizon.
    float g1(const Vec3& w) const {
        float c = std::fabs(w.z);
        return 2.f * c / (c + smith_s(w));
    }

    /// G1(w) / |cos w| = 2 / (|cos| + s(w)); finite everywhere (s >= alpha > 0).
    float g1_over_cos(const Vec3& w) const { return 2.f / (std::fabs(w.z) + smith_s(w)); }

    /// Height-correlated G2(wo, wi) = 1 / (1 + Lambda(wo) + Lambda(wi))
    ///   = 2 |co| |ci| / (s(wo) |ci| + s(wi) |co|).
    float g2(const Vec3& wo, const Vec3& wi) const {
        float co = std::fabs(wo.z), ci = std::fabs(wi.z);
        float den = smith_s(wo) * ci + smith_s(wi) * co;
        return den > 0.f ? 2.f * co * ci / den : 0.f;
    }

    /// G2(wo, wi) / (|cos wo| |cos wi|) = 2 / (s(wo) |ci| + s(wi) |co|) (Filament's V term x 4).
    /// Finite unless both directions lie exactly on the horizon (then 0).
    float g2_over_cos2(const Vec3& wo, const Vec3& wi) const {
        float den = smith_s(wo) * std::fabs(wi.z) + smith_s(wi) * std::fabs(wo.z);
        return den > 0.f ? 2.f / den : 0.f;
    }

    /// Density of visible normals seen from w: D_w(wm) = G1(w) / |cos w| * D(wm) * |w . wm|,
    /// restricted to micro normals that face w (w . wm has the sign of w.z). This is the
    /// density of `sample_visible(w, .)`.
    float visible_pdf(const Vec3& w, const Vec3& wm) const {
        float w_dot_m = dot(w, wm);
        if (!(w_dot_m * w.z > 0.f)) return 0.f;
        return g1_over_cos(w) * d(wm) * std::fabs(w_dot_m);
    }

    /// Sample a visible micro normal for direction w (Heitz 2018, listing 1). For w below
    /// the surface the visible normals of -w are sampled (the microsurface seen from inside),
    /// matching `visible_pdf`. The result always has wm.z > 0.
    Vec3 sample_visible(const Vec3& w, const Vec2& u) const {
        // Section 3.2: transform the view direction to the hemisphere configuration.
        Vec3 vh = normalize(Vec3(m_alpha * w.x, m_alpha * w.y, w.z));
        if (vh.z < 0.f) vh = -vh;
        // Section 4.1: orthonormal basis (with special case if cross product is zero).
        float lensq = vh.x * vh.x + vh.y * vh.y;
        Vec3 t1 = lensq > 0.f ? Vec3(-vh.y, vh.x, 0.f) / std::sqrt(lensq) : Vec3(1.f, 0.f, 0.f);
        Vec3 t2 = cross(vh, t1);
        // Section 4.2: parameterisation of the projected area.
        float r = std::sqrt(u.x);
        float sp, cp;
        sincos_turn(u.y, &sp, &cp);  // φ = 2π u.y (math/sincos.h)
        float p1 = r * cp;
        float p2 = r * sp;
        float s = 0.5f * (1.f + vh.z);
        p2 = (1.f - s) * safe_sqrt(1.f - p1 * p1) + s * p2;
        // Section 4.3: reprojection onto the hemisphere.
        Vec3 nh = t1 * p1 + t2 * p2 + vh * safe_sqrt(1.f - p1 * p1 - p2 * p2);
        // Section 3.4: back to the ellipsoid configuration. The 1e-6 floor keeps wm off the
        // horizon (as pbrt-v4 does), so D(wm) and dot products stay well defined.
        return normalize(Vec3(m_alpha * nh.x, m_alpha * nh.y, std::max(1e-6f, nh.z)));
    }

private:
    float m_alpha;
    float m_alpha2;
};

}  // namespace cmlt
