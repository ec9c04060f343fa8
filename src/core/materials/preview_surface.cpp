/// \file UsdPreviewSurface BSDF. See preview_surface.h for the interface and conventions.
///
/// Modelling choices (each one is what the tests in tests/cpp/materials check against):
///
/// 1. Specular F0 / F90.
///    Metallic workflow: F0 = lerp(((ior-1)/(ior+1))^2, diffuseColor, metallic) (0.04 for
///    ior 1.5), and the Lambert colour is (1 - metallic) * diffuseColor.
///    Specular workflow: F0 = specularColor, Lambert colour = diffuseColor.
///    Schlick with F90 = clamp(50 * max(F0), 0, 1) (Filament's "specular occlusion" rule):
///    F90 = 1 for every physical F0 >= 0.02, and F0 = 0 means "no specular" instead of a
///    spurious grazing highlight, so specularColor = 0 (or ior = 1) gives an exact Lambertian.
///
/// 2. Diffuse under specular (energy-sensible and reciprocal):
///      f_diffuse = C_d / pi * (1 - F(cos wo)) * (1 - F(cos wi)),  F = the specular Schlick.
///    Light that the specular interface reflects at either end cannot reach the diffuse
///    substrate. The product form is symmetric in (wo, wi) (reciprocity holds exactly) and,
///    because the cosine-weighted mean of (1 - F(cos wi)) is (1-F0)*20/21 + (1-F90)/21 < 1,
///    it leaves enough slack for the microfacet specular lobe, whose albedo is at most
///    E_wm[F(wo.wm)]: the white furnace stays <= 1 (tested). The price is ~5-10 % less
///    diffuse than a fully energy-compensated layer; we do not renormalise (like Shirley
///    et al. 1997's coupled diffuse without the normalisation constant).
///
/// 3. Specular: GGX, alpha = roughness^2, Smith height-correlated G2, visible-normal sampling
///    (Heitz 2018). alpha < k_ggx_delta_alpha (1e-3, roughness < ~0.0316) is a Dirac mirror.
///
/// 4. Clearcoat: white GGX lobe, F0 = 0.04 (IOR 1.5), alpha = clearcoatRoughness^2, weight
///    clearcoat * Fc(wo.wm). It is layered additively over everything else, which is
///    attenuated by A = (1 - c Fc(|cos wo|)) (1 - c Fc(|cos wi|)) — symmetric, and at each end
///    removes what the coat reflects at the macro normal.
///
/// 5. Transmission: (1 - opacity) weights a dielectric interface with relative IOR `ior`:
///    exact dielectric Fresnel; smooth (Dirac reflection + refraction) for alpha < 1e-3,
///    rough GGX (Walter et al. 2007, pbrt-v4's DielectricBxDF) otherwise. The interface is
///    physical: +z is outside, wo.z < 0 is inside (relative IOR 1/ior there, total internal
///    reflection). |ior - 1| < 1e-3 is a pure pass-through (Dirac, wi = -wo, f = w/|cos|): the
///    interface cannot deflect or reflect light then, and the GGX half vector would be 0/0.
///    The opaque lobes (diffuse/specular/clearcoat) are two-sided: they reflect into the
///    hemisphere of wo. Transmission is white (UsdPreviewSurface has no transmission colour).
///
/// 6. Sampling: one lobe is picked with probabilities proportional to rough albedo proxies at
///    |cos wo| (opacity * A * mean(C_d (1 - F)), opacity * A * mean(F), c Fc, (1 - opacity) A),
///    mixed 90/10 with a uniform choice over the active lobes so that no active lobe has a
///    vanishing probability. Non-delta samples return the full mixture f and pdf; the mirror
///    direction combines all Dirac reflections (specular, clearcoat, smooth dielectric) into
///    one delta with the summed weight and probability.
#include "materials/preview_surface.h"

#include "materials/fresnel.h"
#include "materials/microfacet.h"
#include "math/safe_math.h"
#include "sampling/warp.h"

#include <array>
#include <cmath>

namespace cmlt {

namespace {

constexpr float k_clearcoat_f0 = 0.04f;     // IOR 1.5
constexpr float k_pass_through_eps = 1e-3f;  // |ior - 1| below this: no interface
constexpr float k_defensive_fraction = 0.1f; // uniform share of the lobe selection
constexpr float k_min_ior = 0.2f, k_max_ior = 5.f;

float mean(const Spectrum& s) { return (s.x + s.y + s.z) * (1.f / 3.f); }

float finite_or(float v, float fallback) { return std::isfinite(v) ? v : fallback; }

Spectrum clamp_colour(const Spectrum& c, const Spectrum& fallback) {
    return {clamp01(finite_or(c.x, fallback.x)), clamp01(finite_or(c.y, fallback.y)),
            clamp01(finite_or(c.z, fallback.z))};
}

/// Flip a direction into the upper hemisphere (two-sided opaque lobes).
Vec3 to_upper(const Vec3& w) { return {w.x, w.y, std::fabs(w.z)}; }

/// GGX reflection f without the Fresnel factor: D(wm) G2 / (4 |cos wo| |cos wi|).
float ggx_reflection_no_fresnel(const GgxDistribution& ggx, const Vec3& wo, const Vec3& wi,
                                const Vec3& wm) {
    return ggx.d(wm) * ggx.g2_over_cos2(wo, wi) * 0.25f;
}

struct ScalarEval {
    float f = 0.f;
    float pdf = 0.f;  ///< pdf conditioned on the dielectric lobe being chosen
};

/// Rough dielectric (Walter et al. 2007; pbrt-v4 DielectricBxDF::f / PDF), both sides.
ScalarEval eval_rough_dielectric(const GgxDistribution& ggx, float eta, const Vec3& wo,
                                 const Vec3& wi, TransportMode mode) {
    float cos_o = wo.z, cos_i = wi.z;
    bool reflection = cos_o * cos_i > 0.f;
    float etap = 1.f;
    if (!reflection) etap = cos_o > 0.f ? eta : 1.f / eta;
    // Generalised half vector, oriented to the outside.
    Vec3 wm = wi * etap + wo;
    if (!(length_squared(wm) > 0.f)) return {};
    wm = normalize(wm);
    if (wm.z < 0.f) wm = -wm;
    // Discard back-facing microfacets.
    float wo_m = dot(wo, wm), wi_m = dot(wi, wm);
    if (!(wo_m * cos_o > 0.f) || !(wi_m * cos_i > 0.f)) return {};
    float fr = fresnel_dielectric(wo_m, eta);
    ScalarEval out;
    if (reflection) {
        out.f = fr * ggx_reflection_no_fresnel(ggx, wo, wi, wm);
        out.pdf = fr * ggx.g1_over_cos(wo) * ggx.d(wm) * 0.25f;
    } else {
        // |wo + etap wi| >= |1 - etap| > 0 away from pass-through, so denom > 0.
        float denom = sqr(wi_m + wo_m / etap);
        if (!(denom > 0.f)) return {};
        float tr = 1.f - fr;
        out.f = tr * ggx.d(wm) * ggx.g2_over_cos2(wo, wi) * std::fabs(wi_m * wo_m) / denom;
        if (mode == TransportMode::Radiance) out.f /= sqr(etap);
        out.pdf = tr * ggx.visible_pdf(wo, wm) * std::fabs(wi_m) / denom;
    }
    return out;
}

}  // namespace

PreviewSurfaceBsdf::PreviewSurfaceBsdf(const PreviewSurfaceParams& in) {
    // Sanitise: clamp to the valid ranges, non-finite -> spec defaults.
    const PreviewSurfaceParams def;
    PreviewSurfaceParams& p = m_params;
    p.diffuse = clamp_colour(in.diffuse, def.diffuse);
    p.specular = clamp_colour(in.specular, def.specular);
    p.use_specular_workflow = in.use_specular_workflow;
    p.metallic = clamp01(finite_or(in.metallic, def.metallic));
    p.roughness = clamp01(finite_or(in.roughness, def.roughness));
    p.clearcoat = clamp01(finite_or(in.clearcoat, def.clearcoat));
    p.clearcoat_roughness = clamp01(finite_or(in.clearcoat_roughness, def.clearcoat_roughness));
    p.opacity = clamp01(finite_or(in.opacity, def.opacity));
    p.ior = (std::isfinite(in.ior) && in.ior > 0.f) ? std::clamp(in.ior, k_min_ior, k_max_ior)
                                                      : 1.f;

    // Workflow -> Lambert colour and specular F0 / F90.
    if (p.use_specular_workflow) {
        m_diffuse = p.diffuse;
        m_f0 = p.specular;
    } else {
        float f0_dielectric = schlick_f0_from_ior(p.ior);
        m_diffuse = p.diffuse * (1.f - p.metallic);
        m_f0 = Spectrum(f0_dielectric) * (1.f - p.metallic) + p.diffuse * p.metallic;
    }
    m_f90 = clamp01(50.f * max_component(m_f0));

    m_alpha = ggx_alpha_from_roughness(p.roughness);
    m_alpha_cc = ggx_alpha_from_roughness(p.clearcoat_roughness);
    m_eta = p.ior;

    // F0 = 1 makes F = 1 at every angle, so the diffuse under it is dead: do not sample it.
    m_has_diffuse = p.opacity > 0.f && max_component(m_diffuse * (Spectrum(1.f) - m_f0)) > 0.f;
    m_has_specular = p.opacity > 0.f && max_component(m_f0) > 0.f;
    m_has_clearcoat = p.clearcoat > 0.f;
    m_specular_delta = m_alpha < k_ggx_delta_alpha;
    m_clearcoat_delta = m_alpha_cc < k_ggx_delta_alpha;
    if (p.opacity >= 1.f)
        m_dielectric = DielectricKind::None;
    else if (std::fabs(m_eta - 1.f) < k_pass_through_eps)
        m_dielectric = DielectricKind::PassThrough;
    else if (m_alpha < k_ggx_delta_alpha)
        m_dielectric = DielectricKind::Smooth;
    else
        m_dielectric = DielectricKind::Rough;
    // lobe_probabilities' uniform share of each active lobe (0: no lobe is active)
    const int active = int(m_has_diffuse) + int(m_has_specular) + int(m_has_clearcoat) +
                       int(m_dielectric != DielectricKind::None);
    if (active > 0) {
        m_uniform_defensive = k_defensive_fraction / float(active);
        m_uniform_all = 1.f / float(active);
    }
}

Spectrum PreviewSurfaceBsdf::specular_fresnel(float cos_theta) const {
    return fresnel_schlick(m_f0, m_f90, cos_theta);
}

float PreviewSurfaceBsdf::clearcoat_fresnel(float cos_theta) const {
    return fresnel_schlick(k_clearcoat_f0, 1.f, cos_theta);
}

float PreviewSurfaceBsdf::clearcoat_attenuation(float abs_cos) const {
    return m_has_clearcoat ? 1.f - m_params.clearcoat * clearcoat_fresnel(abs_cos) : 1.f;
}

PreviewSurfaceBsdf::LobeProbabilities PreviewSurfaceBsdf::lobe_probabilities(
    float abs_cos_o) const {
    for (uint8_t k = 0; k < 2; ++k)
        if (abs_cos_o == m_lobes_cos[k]) {
            m_lobes_newer = k;  // least recently used goes first
            return m_lobes[k];
        }
    const float opacity = m_params.opacity;
    const float att = clearcoat_attenuation(abs_cos_o);
    // inactive lobes keep raw 0: adding +0 to the non-negative total changes no bit
    float raw[4] = {0.f, 0.f, 0.f, 0.f};
    if (m_has_diffuse || m_has_specular) {
        Spectrum fs = specular_fresnel(abs_cos_o);
        if (m_has_diffuse) raw[0] = opacity * att * mean(m_diffuse * (Spectrum(1.f) - fs));
        if (m_has_specular) raw[1] = opacity * att * mean(fs);
    }
    if (m_has_clearcoat) raw[2] = m_params.clearcoat * clearcoat_fresnel(abs_cos_o);
    if (m_dielectric != DielectricKind::None) raw[3] = (1.f - opacity) * att;
    const float total = ((raw[0] + raw[1]) + raw[2]) + raw[3];
    float prob[4] = {0.f, 0.f, 0.f, 0.f};
    if (m_uniform_all > 0.f) {
        const float uniform = total > 0.f ? m_uniform_defensive : m_uniform_all;
        const float scale = total > 0.f ? (1.f - k_defensive_fraction) / total : 0.f;
        if (m_has_diffuse) prob[0] = raw[0] * scale + uniform;
        if (m_has_specular) prob[1] = raw[1] * scale + uniform;
        if (m_has_clearcoat) prob[2] = raw[2] * scale + uniform;
        if (m_dielectric != DielectricKind::None) prob[3] = raw[3] * scale + uniform;
    }
    const uint8_t slot = uint8_t(1 - m_lobes_newer);  // the older one
    m_lobes_newer = slot;
    m_lobes_cos[slot] = abs_cos_o;
    m_lobes[slot] = {prob[0], prob[1], prob[2], prob[3]};
    return m_lobes[slot];
}

PreviewSurfaceBsdf::GgxTerms PreviewSurfaceBsdf::ggx_terms(float alpha, const Vec3& w, const Vec3& wm) {
    const GgxDistribution ggx(alpha);
    GgxTerms t;
    t.d = ggx.d(wm);
    t.s = ggx.smith_s(w);
    t.g1 = 2.f / (std::fabs(w.z) + t.s);  // GgxDistribution::g1_over_cos
    return t;
}

float PreviewSurfaceBsdf::reflection_pdf(const LobeProbabilities& p, float ci, bool faces, const GgxTerms& base,
                                         const GgxTerms& coat) const {
    float pdf = 0.f;
    if (p.diffuse > 0.f) pdf += p.diffuse * ci * k_inv_pi;
    // GGX visible normals, reflected: G1(wo) / |cos wo| * D(wm) / 4, where wm faces wo
    if (p.specular > 0.f && !m_specular_delta && faces) pdf += p.specular * (base.g1 * base.d * 0.25f);
    if (p.clearcoat > 0.f && !m_clearcoat_delta && faces) pdf += p.clearcoat * (coat.g1 * coat.d * 0.25f);
    return pdf;
}

template <bool F, bool P>
Spectrum PreviewSurfaceBsdf::evaluate(const Vec3& wo, const Vec3& wi, TransportMode mode, float* pdf_out) const {
    if constexpr (P) *pdf_out = 0.f;
    const float co = std::fabs(wo.z), ci = std::fabs(wi.z);
    if (co < k_preview_min_cos || ci < k_preview_min_cos) return Spectrum(0.f);
    LobeProbabilities p;
    if constexpr (P) p = lobe_probabilities(co);
    const float opacity = m_params.opacity;
    const float att = F ? clearcoat_attenuation(co) * clearcoat_attenuation(ci) : 1.f;
    const bool reflection = wo.z * wi.z > 0.f;
    const bool rough_dielectric = m_dielectric == DielectricKind::Rough;
    // the rough dielectric's value (for f) and density (for the pdf: the same in either
    // transport mode) from one evaluation
    ScalarEval dielectric;
    if (rough_dielectric && (F || p.dielectric > 0.f))
        dielectric = eval_rough_dielectric(GgxDistribution(m_alpha), m_eta, wo, wi, mode);

    Spectrum f(0.f);
    float pdf = 0.f;
    if (reflection) {
        // Opaque lobes, two-sided: evaluated with both directions flipped above the surface.
        const Vec3 wo_u = to_upper(wo), wi_u = to_upper(wi);
        const Vec3 wm = normalize(wo_u + wi_u);
        const bool spec = !m_specular_delta && ((F && m_has_specular) || (P && p.specular > 0.f));
        const bool coat = !m_clearcoat_delta && ((F && m_has_clearcoat) || (P && p.clearcoat > 0.f));
        const GgxTerms gs = spec ? ggx_terms(m_alpha, wo_u, wm) : GgxTerms();
        const GgxTerms gc = coat ? ggx_terms(m_alpha_cc, wo_u, wm) : GgxTerms();
        if constexpr (F) {
            // GGX reflection without Fresnel: D G2 / (4 |cos wo| |cos wi|), G2 / (|cos wo|
            // |cos wi|) = 2 / (s(wo) |cos wi| + s(wi) |cos wo|) (GgxDistribution::g2_over_cos2)
            const auto no_fresnel = [&](float alpha, const GgxTerms& t) {
                const float den = t.s * std::fabs(wi_u.z) + GgxDistribution(alpha).smith_s(wi_u) * std::fabs(wo_u.z);
                return t.d * (den > 0.f ? 2.f / den : 0.f) * 0.25f;
            };
            Spectrum base(0.f);
            if (m_has_diffuse) {
                Spectrum t_o = Spectrum(1.f) - specular_fresnel(co);
                Spectrum t_i = Spectrum(1.f) - specular_fresnel(ci);
                base += m_diffuse * t_o * t_i * k_inv_pi;
            }
            if (m_has_specular && !m_specular_delta)
                base += specular_fresnel(dot(wo_u, wm)) * no_fresnel(m_alpha, gs);
            f = base * (opacity * att);
            if (rough_dielectric) f += Spectrum((1.f - opacity) * att * dielectric.f);
            if (m_has_clearcoat && !m_clearcoat_delta)
                f += Spectrum(m_params.clearcoat * clearcoat_fresnel(dot(wo_u, wm)) * no_fresnel(m_alpha_cc, gc));
        }
        if constexpr (P) pdf = reflection_pdf(p, ci, dot(wo_u, wm) * wo_u.z > 0.f, gs, gc);
    } else if (F && rough_dielectric) {
        f = Spectrum((1.f - opacity) * att * dielectric.f);
    }
    if constexpr (P) {
        if (p.dielectric > 0.f && rough_dielectric) pdf += p.dielectric * dielectric.pdf;
        *pdf_out = pdf;
    }
    return f;
}

Spectrum PreviewSurfaceBsdf::eval(const Vec3& wo, const Vec3& wi, TransportMode mode) const {
    return evaluate<true, false>(wo, wi, mode, nullptr);
}

float PreviewSurfaceBsdf::pdf(const Vec3& wo, const Vec3& wi) const {
    float pdf = 0.f;
    evaluate<false, true>(wo, wi, TransportMode::Radiance, &pdf);
    return pdf;
}

Spectrum PreviewSurfaceBsdf::eval_pdf(const Vec3& wo, const Vec3& wi, TransportMode mode, float* pdf) const {
    return evaluate<true, true>(wo, wi, mode, pdf);
}

void PreviewSurfaceBsdf::pdf_pair(const Vec3& wo, const Vec3& wi, float* fwd, float* rev) const {
    // pdf both ways: the half vector (wo_u + wi_u is wi_u + wo_u) and D(wm) once
    *fwd = *rev = 0.f;
    const float co = std::fabs(wo.z), ci = std::fabs(wi.z);
    if (co < k_preview_min_cos || ci < k_preview_min_cos) return;
    const LobeProbabilities po = lobe_probabilities(co);
    const LobeProbabilities pi = lobe_probabilities(ci);
    float a = 0.f, b = 0.f;  // pdf(wo, wi), pdf(wi, wo)
    if (wo.z * wi.z > 0.f) {
        const Vec3 wo_u = to_upper(wo), wi_u = to_upper(wi);
        const Vec3 wm = normalize(wo_u + wi_u);
        GgxTerms so, si, co_cc, ci_cc;  // per distribution, seen from wo_u and from wi_u
        if (!m_specular_delta && (po.specular > 0.f || pi.specular > 0.f)) {
            so = ggx_terms(m_alpha, wo_u, wm);
            si = ggx_terms(m_alpha, wi_u, wm);
        }
        if (!m_clearcoat_delta && (po.clearcoat > 0.f || pi.clearcoat > 0.f)) {
            co_cc = ggx_terms(m_alpha_cc, wo_u, wm);
            ci_cc = ggx_terms(m_alpha_cc, wi_u, wm);
        }
        a = reflection_pdf(po, ci, dot(wo_u, wm) * wo_u.z > 0.f, so, co_cc);
        b = reflection_pdf(pi, co, dot(wi_u, wm) * wi_u.z > 0.f, si, ci_cc);
    }
    if (m_dielectric == DielectricKind::Rough) {
        const GgxDistribution ggx(m_alpha);
        if (po.dielectric > 0.f) a += po.dielectric * eval_rough_dielectric(ggx, m_eta, wo, wi, TransportMode::Radiance).pdf;
        if (pi.dielectric > 0.f) b += pi.dielectric * eval_rough_dielectric(ggx, m_eta, wi, wo, TransportMode::Radiance).pdf;
    }
    *fwd = a;
    *rev = b;
}

std::optional<PreviewSurfaceSample> PreviewSurfaceBsdf::sample_mirror(
    const Vec3& wo, const LobeProbabilities& p) const {
    // All Dirac reflections share the mirror direction: return them as one delta whose
    // weight and probability are the sums over the Dirac lobes.
    const float co = std::fabs(wo.z);
    const float opacity = m_params.opacity;
    const float att = sqr(clearcoat_attenuation(co));
    Spectrum weight(0.f);
    float prob = 0.f;
    if (m_has_specular && m_specular_delta) {
        weight += specular_fresnel(co) * (opacity * att);
        prob += p.specular;
    }
    if (m_has_clearcoat && m_clearcoat_delta) {
        weight += Spectrum(m_params.clearcoat * clearcoat_fresnel(co));
        prob += p.clearcoat;
    }
    if (m_dielectric == DielectricKind::Smooth) {
        float fr = fresnel_dielectric(wo.z, m_eta);
        weight += Spectrum((1.f - opacity) * att * fr);
        prob += p.dielectric * fr;
    }
    if (!(prob > 0.f)) return std::nullopt;
    PreviewSurfaceSample s;
    s.wi = Vec3(-wo.x, -wo.y, wo.z);
    s.f = weight / co;
    s.pdf = prob;
    s.is_delta = true;
    s.is_transmission = false;
    s.eta = 1.f;
    return s;
}

std::optional<PreviewSurfaceSample> PreviewSurfaceBsdf::sample(const Vec3& wo, float u_lobe,
                                                               const Vec2& u,
                                                               TransportMode mode) const {
    const float co = std::fabs(wo.z);
    if (co < k_preview_min_cos) return std::nullopt;
    const LobeProbabilities p = lobe_probabilities(co);

    // Pick a lobe; rescale u_lobe to [0, 1) for reuse inside the lobe.
    const std::array<float, 4> probs{p.diffuse, p.specular, p.clearcoat, p.dielectric};
    int lobe = -1;
    float u_rest = std::clamp(u_lobe, 0.f, k_one_minus_eps);
    for (int i = 0; i < 4; ++i) {
        if (!(probs[i] > 0.f)) continue;
        lobe = i;  // the last active lobe also catches rounding leftovers
        if (u_rest < probs[i]) break;
        u_rest -= probs[i];
    }
    if (lobe < 0) return std::nullopt;
    u_rest = std::clamp(u_rest / probs[lobe], 0.f, k_one_minus_eps);

    const float side = wo.z > 0.f ? 1.f : -1.f;
    const Vec3 wo_u = to_upper(wo);
    Vec3 wi;
    switch (lobe) {
        case 0: {  // diffuse: cosine hemisphere on wo's side
            Vec3 w = square_to_cosine_hemisphere(u);
            wi = Vec3(w.x, w.y, side * w.z);
            break;
        }
        case 1:
        case 2: {  // specular or clearcoat: GGX visible normals, reflect
            bool delta = lobe == 1 ? m_specular_delta : m_clearcoat_delta;
            if (delta) return sample_mirror(wo, p);
            GgxDistribution ggx(lobe == 1 ? m_alpha : m_alpha_cc);
            Vec3 wm = ggx.sample_visible(wo_u, u);
            Vec3 w = reflect(wo_u, wm);
            if (!(w.z > 0.f)) return std::nullopt;
            wi = Vec3(w.x, w.y, side * w.z);
            break;
        }
        default: {  // dielectric
            const float opacity = m_params.opacity;
            if (m_dielectric == DielectricKind::PassThrough) {
                PreviewSurfaceSample s;
                s.wi = -wo;
                s.f = Spectrum((1.f - opacity) * sqr(clearcoat_attenuation(co)) / co);
                s.pdf = p.dielectric;
                s.is_delta = true;
                s.is_transmission = true;
                s.eta = 1.f;
                s.pass_through = true;
                return s;
            }
            if (m_dielectric == DielectricKind::Smooth) {
                float fr = fresnel_dielectric(wo.z, m_eta);
                if (u_rest < fr) return sample_mirror(wo, p);
                float etap = 1.f;
                Vec3 wt;
                if (!refract(wo, Vec3(0.f, 0.f, 1.f), m_eta, &etap, &wt)) return std::nullopt;
                float ci = std::fabs(wt.z);
                if (ci < k_preview_min_cos || wt.z * wo.z >= 0.f) return std::nullopt;
                float ft = (1.f - opacity) * clearcoat_attenuation(co) *
                           clearcoat_attenuation(ci) * (1.f - fr) / ci;
                if (mode == TransportMode::Radiance) ft /= sqr(etap);
                PreviewSurfaceSample s;
                s.wi = wt;
                s.f = Spectrum(ft);
                s.pdf = p.dielectric * (1.f - fr);
                s.is_delta = true;
                s.is_transmission = true;
                s.eta = etap;
                return s;
            }
            // Rough: visible normal, then reflect or refract by the microfacet Fresnel.
            GgxDistribution ggx(m_alpha);
            Vec3 wm = ggx.sample_visible(wo, u);
            float fr = fresnel_dielectric(dot(wo, wm), m_eta);
            if (u_rest < fr) {
                wi = reflect(wo, wm);
                if (!(wi.z * wo.z > 0.f)) return std::nullopt;
            } else {
                float etap = 1.f;
                if (!refract(wo, wm, m_eta, &etap, &wi)) return std::nullopt;
                if (!(wi.z * wo.z < 0.f)) return std::nullopt;
            }
            break;
        }
    }

    // Non-delta: full mixture value and pdf (one-sample MIS over the lobes).
    if (std::fabs(wi.z) < k_preview_min_cos) return std::nullopt;
    PreviewSurfaceSample s;
    s.wi = wi;
    s.f = eval_pdf(wo, wi, mode, &s.pdf);
    if (!(s.pdf > 0.f) || !std::isfinite(s.pdf)) return std::nullopt;
    s.is_delta = false;
    s.is_transmission = wi.z * wo.z < 0.f;
    s.eta = s.is_transmission ? (wo.z > 0.f ? m_eta : 1.f / m_eta) : 1.f;
    return s;
}

bool PreviewSurfaceBsdf::has_delta() const {
    return (m_has_specular && m_specular_delta) || (m_has_clearcoat && m_clearcoat_delta) ||
           m_dielectric == DielectricKind::Smooth || m_dielectric == DielectricKind::PassThrough;
}

float PreviewSurfaceBsdf::pass_through(float abs_cos, float* prob) const {
    *prob = 0.f;
    if (m_dielectric != DielectricKind::PassThrough || abs_cos < k_preview_min_cos) return 0.f;
    // As sample()'s pass-through branch: f = (1 - opacity) A(co)^2 / co at wi = -wo.
    *prob = lobe_probabilities(abs_cos).dielectric;
    return (1.f - m_params.opacity) * sqr(clearcoat_attenuation(abs_cos));
}

bool PreviewSurfaceBsdf::is_pure_delta() const {
    bool any_smooth = m_has_diffuse || (m_has_specular && !m_specular_delta) ||
                      (m_has_clearcoat && !m_clearcoat_delta) ||
                      m_dielectric == DielectricKind::Rough;
    return has_delta() && !any_smooth;
}

Spectrum PreviewSurfaceBsdf::albedo_estimate() const {
    const float opacity = m_params.opacity, c = m_params.clearcoat;
    // Cosine-weighted hemispherical mean of Schlick: F0 + (F90 - F0) / 21.
    Spectrum fs_mean = m_has_specular ? m_f0 + (Spectrum(m_f90) - m_f0) * (1.f / 21.f)
                                      : Spectrum(0.f);
    Spectrum base = (m_diffuse * (Spectrum(1.f) - m_f0) * (Spectrum(1.f) - fs_mean) + fs_mean) *
                    opacity;
    if (m_dielectric != DielectricKind::None) base += Spectrum(1.f - opacity);
    float fc_mean = k_clearcoat_f0 + (1.f - k_clearcoat_f0) * (1.f / 21.f);
    Spectrum a = base * (1.f - c * fc_mean) + Spectrum(c * fc_mean);
    return {clamp01(a.x), clamp01(a.y), clamp01(a.z)};
}

}  // namespace cmlt
