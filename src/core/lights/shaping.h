#pragma once
/// \file UsdLux ShapingAPI (cone and focus) as a direction-dependent factor on the
/// emitted radiance of rect, disk, sphere and cylinder lights.
///
/// With theta the angle between the emission direction d and the light's emission axis
/// (local -Z in world space), A = shaping:cone:angle (half-angle, degrees, clamped to
/// [0, 180]), s = shaping:cone:softness (clamped to [0, 1]), f = shaping:focus (>= 0) and
/// T = shaping:focusTint:
///
///     cone(theta)  = smoothstep(cos A, cos(A * (1 - s)), cos theta)   (s = 0: a hard
///                    cutoff, 1 inside the cone, 0 outside; A = 180: no cone)
///     focus(theta) = T + (1 - T) * max(cos theta, 0)^f                 (f = 0: 1)
///     L(d)         = L * cone(theta) * focus(theta)
///
/// This follows the intent of the UsdLux spec (the cone limits the spread about the
/// primary axis with a soft edge growing inward as softness goes to 1; focus pulls the
/// light toward the axis as a cosine power, focusTint colours the off-axis falloff) and
/// matches the common renderer implementations (Karma, RenderMan). Sampling is not
/// changed: the factor multiplies the radiance in le (camera/BSDF hits), sample_li and
/// sample_le, so the estimators stay unbiased. power() is scaled by an approximation.
#include "math/vec.h"

#include <algorithm>
#include <cmath>

namespace cmlt {

struct Shaping {
    bool active = false;
    Vec3 axis{0.f, 0.f, -1.f};   ///< unit world emission axis (local -Z)
    float cos_outer = -1.f;      ///< cos A
    float cos_inner = -1.f;      ///< cos(A (1 - s))
    float focus = 0.f;
    Spectrum tint{0.f};

    Shaping() = default;
    /// angle_deg, softness, focus as authored; `axis` the unit world -Z of the light.
    Shaping(const Vec3& axis_world, float angle_deg, float softness, float focus_,
            const Spectrum& focus_tint) {
        axis = axis_world;
        float a = std::isfinite(angle_deg) ? std::clamp(angle_deg, 0.f, 180.f) : 180.f;
        float s = std::isfinite(softness) ? std::clamp(softness, 0.f, 1.f) : 0.f;
        focus = (std::isfinite(focus_) && focus_ > 0.f) ? focus_ : 0.f;
        tint = Spectrum(std::clamp(focus_tint.x, 0.f, 1.f), std::clamp(focus_tint.y, 0.f, 1.f),
                        std::clamp(focus_tint.z, 0.f, 1.f));
        constexpr float deg = 3.14159265358979323846f / 180.f;
        cos_outer = a >= 180.f ? -2.f : std::cos(a * deg);
        cos_inner = a >= 180.f ? -2.f : std::cos(a * (1.f - s) * deg);
        active = a < 180.f || focus > 0.f;
    }

    /// Factor for unit emission direction d (world).
    Spectrum eval(const Vec3& d) const {
        if (!active) return Spectrum(1.f);
        float c = dot(axis, d);
        float cone = 1.f;
        if (cos_outer > -2.f) {
            if (c < cos_outer) return Spectrum(0.f);
            if (c < cos_inner) {
                float x = (c - cos_outer) / (cos_inner - cos_outer);
                x = std::clamp(x, 0.f, 1.f);
                cone = x * x * (3.f - 2.f * x);
            }
        }
        if (!(focus > 0.f)) return Spectrum(cone);
        float f = std::pow(std::max(c, 0.f), focus);
        return (tint + (Spectrum(1.f) - tint) * f) * cone;
    }

    /// Rough fraction of the unshaped power kept: cone solid-angle fraction (cosine
    /// weighted about the axis for a one-sided planar emitter, uniform otherwise) times
    /// the focus lobe's cosine-weighted mean. Used only for light selection.
    float power_factor(bool planar) const {
        if (!active) return 1.f;
        float c = cos_outer > -2.f ? 0.5f * (cos_outer + cos_inner) : -1.f;
        float frac = planar ? (c <= 0.f ? 1.f : 1.f - c * c) : 0.5f * (1.f - c);
        float lum_t = luminance(tint);
        float foc = focus > 0.f ? lum_t + (1.f - lum_t) * 2.f / (focus + 2.f) : 1.f;
        return std::max(frac * foc, 1e-4f);
    }
};

}  // namespace cmlt
