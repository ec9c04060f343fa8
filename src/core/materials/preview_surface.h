#pragma once
/// \file UsdPreviewSurface as a physically based BSDF (diffuse, GGX specular, clearcoat,
/// dielectric transmission), usable by the path tracer, BDPT and the MLT family.
///
/// Conventions (shared with the other BSDFs):
///  - Directions are in the local shading frame, z = shading normal, both `wo` and `wi`
///    point away from the surface. `wo.z < 0` means `wo` is on the back / inside.
///  - `eval` returns the BSDF value f (not multiplied by |cos wi|); pdfs are per solid angle.
///  - Delta (Dirac) lobes are never returned by `eval`/`pdf`; `sample` returns them with
///    `is_delta`, `f` = (Dirac weight) / |cos wi| and `pdf` = the discrete probability of
///    picking that delta, so that f |cos wi| / pdf is the throughput weight in all cases.
///  - A direction exactly on the horizon (|z| < k_preview_min_cos) scatters nothing.
///
/// Lobes and how they combine (all choices are explained at the top of preview_surface.cpp):
///
///   f = A(wo, wi) * [ opacity * (f_diffuse + f_specular) + (1 - opacity) * f_dielectric ]
///       + clearcoat * f_clearcoat
///   A(wo, wi) = (1 - clearcoat * Fc(|cos wo|)) * (1 - clearcoat * Fc(|cos wi|))
///
/// The opaque lobes (diffuse, specular, clearcoat) are two-sided: they reflect into the
/// hemisphere of `wo`, whichever it is. The dielectric lobe sees a real interface: outside is
/// +z, inside is -z, relative IOR `ior` (interior / exterior).
#include "math/vec.h"

#include <optional>

namespace cmlt {

/// Which quantity a path carries; selects the non-symmetric scaling of refraction.
/// Radiance (camera paths): transmitted f is divided by etap^2 (radiance compression).
/// Importance (light paths): no scaling. See Veach 1997, section 5.2.
enum class TransportMode { Radiance, Importance };

/// UsdPreviewSurface inputs (https://openusd.org/release/spec_usdpreviewsurface.html),
/// already evaluated at the shading point. The constructor clamps every field to its valid
/// range and replaces non-finite values by the spec defaults; nothing here can produce NaN.
struct PreviewSurfaceParams {
    /// diffuseColor: albedo (metallic workflow: also the metal's F0). [0,1]^3, default 0.18.
    Spectrum diffuse{0.18f, 0.18f, 0.18f};
    /// specularColor: F0 of the specular lobe in the specular workflow. [0,1]^3, default 0.
    Spectrum specular{0.f, 0.f, 0.f};
    /// useSpecularWorkflow: true = specularColor drives F0, metallic is ignored.
    bool use_specular_workflow = false;
    /// metallic: [0,1], default 0 (metallic workflow only).
    float metallic = 0.f;
    /// roughness: [0,1], default 0.5; alpha = roughness^2; alpha < 1e-3 is a perfect mirror.
    float roughness = 0.5f;
    /// clearcoat: weight of the white clearcoat lobe (IOR 1.5), [0,1], default 0.
    float clearcoat = 0.f;
    /// clearcoatRoughness: [0,1], default 0.01.
    float clearcoat_roughness = 0.01f;
    /// opacity: [0,1], default 1. (1 - opacity) is the weight of the dielectric
    /// (glass-like) transmission lobe.
    float opacity = 1.f;
    /// ior: interior / exterior IOR, default 1.5. Clamped to [0.2, 5]; non-positive or
    /// non-finite values become 1 (no interface). Used for the dielectric lobe and, in the
    /// metallic workflow, for the dielectric F0 = ((ior - 1) / (ior + 1))^2.
    float ior = 1.5f;
};

/// One sampled direction. (Named PreviewSurfaceSample rather than BsdfSample because
/// materials/bsdf_sample.h already defines cmlt::BsdfSample {wi, f, pdf, is_delta}; once that
/// struct gains `is_transmission` and `eta` this one can be replaced by it.)
struct PreviewSurfaceSample {
    Vec3 wi;                       ///< sampled direction, local frame, unit
    Spectrum f;                    ///< BSDF value (not divided by pdf, not times |cos wi|)
    float pdf = 0.f;               ///< solid-angle pdf, or the discrete probability if is_delta
    bool is_delta = false;         ///< wi came from a Dirac lobe
    bool is_transmission = false;  ///< wi is on the other side of the surface
    float eta = 1.f;               ///< relative IOR crossed (eta_t / eta_i); 1 for reflection
    bool pass_through = false;     ///< the pass-through lobe: wi = -wo, no interface
};

/// Cosines smaller than this are treated as exactly on the horizon (nothing scatters).
/// It only guards 1/cos overflow of Dirac weights for denormal cosines.
constexpr float k_preview_min_cos = 1e-12f;

/// UsdPreviewSurface BSDF. Cheap to construct (per shading point); immutable afterwards.
class PreviewSurfaceBsdf {
public:
    explicit PreviewSurfaceBsdf(const PreviewSurfaceParams& params);

    /// Sum of all non-delta lobes at (wo, wi). Zero for delta lobes.
    Spectrum eval(const Vec3& wo, const Vec3& wi, TransportMode mode) const;
    /// Exact mixture pdf of `sample` over the non-delta lobes (lobe selection probabilities
    /// included). Zero for delta lobes. Integrates to 1 - P(delta) - P(sample fails).
    float pdf(const Vec3& wo, const Vec3& wi) const;
    /// eval(wo, wi, mode) and, in *pdf, pdf(wo, wi) — the same floats — computed together:
    /// the half vector, the microfacet distribution, the masking of wo and the rough
    /// dielectric's terms once for both (next-event estimation and `sample` need both).
    Spectrum eval_pdf(const Vec3& wo, const Vec3& wi, TransportMode mode, float* pdf) const;
    /// pdf(wo, wi) in *fwd and pdf(wi, wo) in *rev — the same floats — computed together
    /// (the half vector and D are the same both ways): BDPT asks for both at a vertex.
    void pdf_pair(const Vec3& wo, const Vec3& wi, float* fwd, float* rev) const;
    /// Pick a lobe with `u_lobe` (the remainder of u_lobe picks reflection vs refraction of
    /// the dielectric), then a direction with `u`. Non-delta samples carry the full mixture
    /// f = eval(wo, wi) and pdf = pdf(wo, wi) (one-sample MIS over the lobes). Returns
    /// std::nullopt when the sample is invalid (below the horizon, wo on the horizon, no lobe).
    std::optional<PreviewSurfaceSample> sample(const Vec3& wo, float u_lobe, const Vec2& u,
                                               TransportMode mode) const;

    /// True if some lobe is a Dirac delta.
    bool has_delta() const;
    /// True if every active lobe is a Dirac delta (smooth glass, mirror, pass-through);
    /// eval/pdf are then 0 everywhere and light sampling is pointless.
    bool is_pure_delta() const;
    /// The dielectric lobe is a pass-through (|ior - 1| < 1e-3 with opacity < 1, e.g. an
    /// opacityThreshold cut-out): light goes straight through without an interface.
    bool has_pass_through() const { return m_dielectric == DielectricKind::PassThrough; }
    /// For |cos wo| = abs_cos: the pass-through lobe's weight T (f |cos wi| of its Dirac
    /// direction wi = -wo, as `sample` returns it: (1 - opacity) times the clearcoat
    /// attenuation at both ends) and, in *prob, the probability with which `sample`
    /// picks it. 0 (and *prob = 0) without a pass-through lobe or on the horizon. The
    /// same at -wo, so a shadow ray can evaluate a crossing in either direction.
    float pass_through(float abs_cos, float* prob) const;
    /// Rough hemispherical albedo for AOVs and Russian roulette: normal incidence, Schlick
    /// averaged over the cosine-weighted hemisphere, microfacet shadowing ignored.
    Spectrum albedo_estimate() const;

    /// The parameters after clamping/sanitising.
    const PreviewSurfaceParams& params() const { return m_params; }

    /// The constants of the model path/diffuse_lanes.h shades in lanes: opaque, no
    /// clearcoat, a diffuse lobe and/or a rough (non-Dirac) GGX specular lobe.
    struct LaneConstants {
        Spectrum diffuse;  ///< the Lambert colour
        Spectrum f0;       ///< specular F0
        float f90 = 1.f;
        float alpha = 0.f;
        bool has_diffuse = false, has_specular = false;
    };
    /// This BSDF's LaneConstants, or false if it is not of that model.
    bool lane_constants(LaneConstants* c) const {
        if (m_dielectric != DielectricKind::None || m_has_clearcoat) return false;
        if (!m_has_diffuse && !m_has_specular) return false;
        if (m_has_specular && m_specular_delta) return false;
        c->diffuse = m_diffuse;
        c->f0 = m_f0;
        c->f90 = m_f90;
        c->alpha = m_alpha;
        c->has_diffuse = m_has_diffuse;
        c->has_specular = m_has_specular;
        return true;
    }

private:
    enum class DielectricKind { None, Smooth, Rough, PassThrough };
    struct LobeProbabilities {
        float diffuse = 0.f, specular = 0.f, clearcoat = 0.f, dielectric = 0.f;
    };

    LobeProbabilities lobe_probabilities(float abs_cos_o) const;
    /// eval (F), pdf (P) or both at (wo, wi), each term computed once.
    template <bool F, bool P>
    Spectrum evaluate(const Vec3& wo, const Vec3& wi, TransportMode mode, float* pdf) const;
    /// One GGX distribution's terms at half vector wm seen from w: D(wm), the Smith term
    /// s(w) and G1(w) / |cos w| (GgxDistribution's d, smith_s, g1_over_cos).
    struct GgxTerms {
        float d = 0.f, s = 0.f, g1 = 0.f;
    };
    static GgxTerms ggx_terms(float alpha, const Vec3& w, const Vec3& wm);
    /// The reflection lobes' density toward a direction of |cos| ci, seen from a direction
    /// with lobe probabilities p whose half vector it `faces`, from the base and clearcoat
    /// distributions' terms (read where their lobe has a density).
    float reflection_pdf(const LobeProbabilities& p, float ci, bool faces, const GgxTerms& base,
                         const GgxTerms& coat) const;
    Spectrum specular_fresnel(float cos_theta) const;
    float clearcoat_fresnel(float cos_theta) const;
    float clearcoat_attenuation(float abs_cos) const;
    std::optional<PreviewSurfaceSample> sample_mirror(const Vec3& wo,
                                                      const LobeProbabilities& p) const;

    PreviewSurfaceParams m_params;
    Spectrum m_diffuse;      ///< effective Lambert colour ((1 - metallic) * diffuse in metallic)
    Spectrum m_f0;           ///< specular F0
    float m_f90 = 1.f;       ///< specular F90 (Filament's rule, see .cpp)
    float m_alpha = 0.f;     ///< base / dielectric GGX alpha
    float m_alpha_cc = 0.f;  ///< clearcoat GGX alpha
    float m_eta = 1.5f;      ///< dielectric relative IOR
    bool m_has_diffuse = false, m_has_specular = false, m_has_clearcoat = false;
    bool m_specular_delta = false, m_clearcoat_delta = false;
    DielectricKind m_dielectric = DielectricKind::None;
    /// k_defensive_fraction / n and 1 / n, n the active lobes (lobe_probabilities; 0: none)
    float m_uniform_defensive = 0.f, m_uniform_all = 0.f;
    /// lobe_probabilities of the last two |cos θ| asked for, the older one replaced: sample,
    /// eval and pdf of one vertex ask for the same wo, and pdf_pair also for each wi (a
    /// BDPT vertex's connections alternate between its wo and a new wi; one slot lost wo
    /// at every connection). A BSDF lives at one hit, used by one thread.
    mutable float m_lobes_cos[2] = {-1.f, -1.f};
    mutable LobeProbabilities m_lobes[2];
    mutable uint8_t m_lobes_newer = 0;  ///< the slot filled last
};

}  // namespace cmlt
