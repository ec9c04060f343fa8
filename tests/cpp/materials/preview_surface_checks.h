#pragma once
// Helpers of the UsdPreviewSurface tests (test_preview_surface.cpp,
// test_preview_surface_lobes.cpp): tolerant comparisons, printing, the sample weight and
// the white-furnace estimate of a directional albedo.
#include "bsdf_test_util.h"
#include "materials/preview_surface.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <optional>
#include <sstream>
#include <string>

namespace cmlt::test {

inline constexpr double k_pi_d = 3.14159265358979323846;

/// Print furnace values etc. when CMLT_TEST_VERBOSE is set (never needed to pass).
inline bool verbose() { return std::getenv("CMLT_TEST_VERBOSE") != nullptr; }

inline bool near_rel(float a, float b, float rel, float abs_tol) {
    return std::fabs(a - b) <= rel * std::max(std::fabs(a), std::fabs(b)) + abs_tol;
}

inline bool near_rel(const Spectrum& a, const Spectrum& b, float rel, float abs_tol) {
    return near_rel(a.x, b.x, rel, abs_tol) && near_rel(a.y, b.y, rel, abs_tol) &&
           near_rel(a.z, b.z, rel, abs_tol);
}

inline std::string str(const Vec3& v) {
    std::ostringstream os;
    os.precision(9);
    os << "(" << v.x << ", " << v.y << ", " << v.z << ")";
    return os.str();
}

inline Spectrum weight_of(const PreviewSurfaceSample& s) { return s.f * (std::fabs(s.wi.z) / s.pdf); }

struct MeanEstimate {
    double mean = 0, std_error = 0;
};

/// E[f |cos wi| / pdf] with `n` samples (failed samples count as 0): the directional albedo.
/// In Radiance mode the 1/etap^2 factor of refraction is undone (multiplied by eta^2).
inline MeanEstimate furnace(const PreviewSurfaceBsdf& bsdf, const Vec3& wo, int n, TransportMode mode,
                            uint32_t stream, int channel = 1) {
    TestRng rng(14, stream);
    double sum = 0, sum2 = 0;
    for (int i = 0; i < n; ++i) {
        float ul = rng.get1d();
        Vec2 u = rng.get2d();
        std::optional<PreviewSurfaceSample> s = bsdf.sample(wo, ul, u, mode);
        double w = 0;
        if (s) {
            w = weight_of(*s)[channel];
            if (mode == TransportMode::Radiance && s->is_transmission) w *= double(s->eta) * s->eta;
        }
        sum += w;
        sum2 += w * w;
    }
    MeanEstimate e;
    e.mean = sum / n;
    e.std_error = std::sqrt(std::max(0.0, sum2 / n - e.mean * e.mean) / (n - 1));
    return e;
}

}  // namespace cmlt::test
