#pragma once
/// \file Shared helpers for the BSDF tests: named parameter sets, directions, random numbers.
#include "materials/preview_surface.h"
#include "math/safe_math.h"
#include "math/vec.h"
#include "sampling/rng.h"

#include <cmath>
#include <ostream>
#include <string>
#include <vector>

namespace cmlt::test {

/// Direction at polar angle theta (degrees) and azimuth phi (radians). Negative `side` puts it
/// below the surface (inside). theta = 90 is exactly on the horizon.
inline Vec3 direction_deg(float theta_deg, float phi = 0.7f, float side = 1.f) {
    float t = radians(theta_deg);
    float z = theta_deg == 90.f ? 0.f : std::cos(t);
    float s = std::sin(t);
    return {s * std::cos(phi), s * std::sin(phi), side * z};
}

/// Uniform random numbers for tests (Philox via the renderer's own sampler, test stream).
class TestRng {
public:
    explicit TestRng(uint64_t seed, uint32_t stream = 0) : m_seed(seed), m_stream(stream) {}
    float get1d() { return next().get1d(); }
    Vec2 get2d() { return next().get2d(); }
    Vec3 uniform_sphere() {
        Vec2 u = get2d();
        float z = 1.f - 2.f * u.x;
        float r = safe_sqrt(1.f - z * z);
        float phi = 2.f * k_pi * u.y;
        return {r * std::cos(phi), r * std::sin(phi), z};
    }

private:
    PixelSampler next() { return PixelSampler(m_seed, m_stream, m_index++, RngStream::test); }
    uint64_t m_seed;
    uint32_t m_stream;
    uint32_t m_index = 0;
};

/// Textbook GGX (Walter et al. 2007 eq. 33; Heitz 2014 eq. 72 and 99) in double precision,
/// written independently of materials/microfacet.h to serve as a reference.
struct TextbookGgx {
    double alpha;
    double d(double cos_m) const {
        if (cos_m <= 0) return 0;
        double c2 = cos_m * cos_m, t2 = (1 - c2) / c2;
        return alpha * alpha / (3.14159265358979323846 * c2 * c2 * std::pow(alpha * alpha + t2, 2));
    }
    double lambda(double cos_w) const {
        double c2 = cos_w * cos_w, t2 = (1 - c2) / c2;
        return 0.5 * (-1 + std::sqrt(1 + alpha * alpha * t2));
    }
    double g2(double cos_o, double cos_i) const {
        return 1.0 / (1.0 + lambda(cos_o) + lambda(cos_i));
    }
};

/// A named parameter set.
struct NamedParams {
    std::string name;
    PreviewSurfaceParams params;
};
inline std::ostream& operator<<(std::ostream& os, const NamedParams& p) { return os << p.name; }

/// Pure Lambert: specular workflow with specularColor = 0 (F0 = 0 disables the specular lobe).
inline PreviewSurfaceParams lambert(const Spectrum& albedo) {
    PreviewSurfaceParams p;
    p.diffuse = albedo;
    p.use_specular_workflow = true;
    p.specular = Spectrum(0.f);
    p.roughness = 0.5f;
    return p;
}

/// Metallic workflow conductor (metallic = 1): F0 = colour.
inline PreviewSurfaceParams metal(const Spectrum& f0, float roughness) {
    PreviewSurfaceParams p;
    p.diffuse = f0;
    p.metallic = 1.f;
    p.roughness = roughness;
    return p;
}

/// Metallic workflow dielectric: diffuse + 0.04 GGX specular.
inline PreviewSurfaceParams plastic(const Spectrum& albedo, float roughness) {
    PreviewSurfaceParams p;
    p.diffuse = albedo;
    p.metallic = 0.f;
    p.roughness = roughness;
    p.ior = 1.5f;
    return p;
}

/// Specular workflow: diffuse colour + specular F0 colour.
inline PreviewSurfaceParams specular_workflow(const Spectrum& diffuse, const Spectrum& specular,
                                              float roughness) {
    PreviewSurfaceParams p;
    p.use_specular_workflow = true;
    p.diffuse = diffuse;
    p.specular = specular;
    p.roughness = roughness;
    return p;
}

/// Glass: opacity 0, so the dielectric is the only lobe.
inline PreviewSurfaceParams glass(float roughness, float ior) {
    PreviewSurfaceParams p;
    p.diffuse = Spectrum(0.f);
    p.opacity = 0.f;
    p.roughness = roughness;
    p.ior = ior;
    return p;
}

inline PreviewSurfaceParams with_clearcoat(PreviewSurfaceParams p, float clearcoat,
                                           float clearcoat_roughness) {
    p.clearcoat = clearcoat;
    p.clearcoat_roughness = clearcoat_roughness;
    return p;
}

inline PreviewSurfaceParams with_opacity(PreviewSurfaceParams p, float opacity) {
    p.opacity = opacity;
    return p;
}

/// Every non-delta configuration used by the statistical tests.
inline std::vector<NamedParams> smooth_configurations() {
    return {
        {"lambert", lambert(Spectrum(0.8f, 0.5f, 0.2f))},
        {"metal_r0.2", metal(Spectrum(0.95f, 0.64f, 0.54f), 0.2f)},
        {"metal_r0.5", metal(Spectrum(0.95f, 0.64f, 0.54f), 0.5f)},
        {"metal_r1.0", metal(Spectrum(0.95f, 0.64f, 0.54f), 1.0f)},
        {"plastic_r0.4", plastic(Spectrum(0.5f, 0.5f, 0.5f), 0.4f)},
        {"specular_workflow", specular_workflow(Spectrum(0.6f, 0.3f, 0.1f), Spectrum(0.2f), 0.35f)},
        {"clearcoat_mix", with_clearcoat(plastic(Spectrum(0.7f, 0.4f, 0.3f), 0.6f), 1.f, 0.2f)},
        {"rough_glass_r0.3", glass(0.3f, 1.5f)},
        {"rough_glass_r0.7_ior1.33", glass(0.7f, 1.33f)},
        {"translucent_mix",
         with_opacity(with_clearcoat(plastic(Spectrum(0.5f), 0.5f), 0.5f, 0.3f), 0.5f)},
        {"rough_bubble_ior0.75", glass(0.4f, 0.75f)},
    };
}

/// Configurations with at least one Dirac lobe (not chi^2-testable as a whole).
inline std::vector<NamedParams> delta_configurations() {
    return {
        {"mirror_metal", metal(Spectrum(0.95f, 0.64f, 0.54f), 0.f)},
        {"smooth_plastic", plastic(Spectrum(0.5f), 0.f)},
        {"smooth_glass", glass(0.f, 1.5f)},
        {"pass_through", glass(0.3f, 1.f)},
        {"smooth_clearcoat_over_rough", with_clearcoat(plastic(Spectrum(0.6f), 0.5f), 1.f, 0.f)},
        {"half_opaque_smooth_glass", with_opacity(plastic(Spectrum(0.5f), 0.f), 0.5f)},
        {"white_mirror", metal(Spectrum(1.f), 0.f)},
    };
}

/// White (albedo-1) stress cases for energy conservation: where the layering approximations
/// (diffuse under specular, base under clearcoat) could push the albedo above 1.
inline std::vector<NamedParams> energy_stress_configurations() {
    const Spectrum white(1.f);
    return {
        {"white_plastic_r0", plastic(white, 0.f)},
        {"white_plastic_r0.3", plastic(white, 0.3f)},
        {"white_plastic_r1", plastic(white, 1.f)},
        {"white_plastic_ior2.5_r0.5", [] { PreviewSurfaceParams p = plastic(Spectrum(1.f), 0.5f); p.ior = 2.5f; return p; }()},
        {"white_spec_workflow_s0.5", specular_workflow(white, Spectrum(0.5f), 0.3f)},
        {"white_spec_workflow_s1_r0", specular_workflow(white, white, 0.f)},
        {"white_clearcoat_plastic", with_clearcoat(plastic(white, 0.5f), 1.f, 0.5f)},
        {"white_clearcoat_metal", with_clearcoat(metal(white, 0.2f), 1.f, 0.8f)},
        {"white_clearcoat_mirror", with_clearcoat(metal(white, 0.f), 1.f, 0.3f)},
        {"white_clearcoat_glass", with_clearcoat(glass(0.3f, 1.5f), 1.f, 0.3f)},
        {"white_translucent", with_opacity(plastic(white, 0.5f), 0.5f)},
    };
}

}  // namespace cmlt::test
