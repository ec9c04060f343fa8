#pragma once
/// \file The BSDF at a surface point: a lobe model in its local shading frame.
///
/// `Bsdf` is a value type (no heap allocation per hit) holding a std::variant of lobe
/// models (Lambert for legacy materials, UsdPreviewSurface); the integrators call eval /
/// pdf / sample in world space and never see the model. `is_delta` on samples and
/// `has_non_delta()` tell the integrator when light sampling and MIS apply.
///
/// Sidedness: the shading frame's +z is the shading normal, which lies on the geometric
/// normal's side (the "outside" of a dielectric). A pair (wo, wi) is a *reflection* when both
/// lie on the same side of the geometric normal and a *transmission* otherwise; the model
/// is only asked about pairs whose shading-frame classification agrees with the geometric
/// one (eval / pdf return 0 and sample fails otherwise). So reflection never leaks light
/// through the surface because of shading normals, and transmission works.
///
/// `TransportMode::Radiance` (camera paths, the default) scales refraction by 1/eta^2;
/// light paths (BDPT, light tracing) pass `TransportMode::Importance`.
#include "materials/bsdf_sample.h"
#include "materials/lambertian.h"
#include "materials/material.h"
#include "materials/preview_surface.h"
#include "math/frame.h"

#include <cmath>
#include <type_traits>
#include <variant>

namespace cmlt {

class Bsdf {
public:
    using Model = std::variant<LambertianBsdf, PreviewSurfaceBsdf>;

    Bsdf(const Model& model, const Vec3& ns, const Vec3& ng)
        : m_model(model), m_frame(ns), m_ng(ng) {}

    /// The material with its constant values (no textures, no normal map); see
    /// materials/material_eval.h for the textured version used by the integrators.
    static Bsdf from_material(const Material& mat, const Vec3& ns, const Vec3& ng);

    Spectrum eval(const Vec3& wo, const Vec3& wi,
                  TransportMode mode = TransportMode::Radiance) const {
        return evaluate<true, false>(wo, wi, mode, nullptr);
    }
    float pdf(const Vec3& wo, const Vec3& wi) const {
        float p = 0.f;
        evaluate<false, true>(wo, wi, TransportMode::Radiance, &p);
        return p;
    }
    /// eval(wo, wi, mode) and, in *pdf, pdf(wo, wi): the same floats, the side test and
    /// the local directions once, the model's shared terms once
    /// (PreviewSurfaceBsdf::eval_pdf).
    Spectrum eval_pdf(const Vec3& wo, const Vec3& wi, TransportMode mode, float* pdf) const {
        return evaluate<true, true>(wo, wi, mode, pdf);
    }
    /// pdf(wo, wi) in *fwd and pdf(wi, wo) in *rev: the same floats, the side test and the
    /// local directions once (the test is symmetric), the model's shared terms once.
    void pdf_pair(const Vec3& wo, const Vec3& wi, float* fwd, float* rev) const {
        *fwd = *rev = 0.f;
        if (const auto* lambert = std::get_if<LambertianBsdf>(&m_model)) {
            float lz, iz;
            if (!consistent_cosines(wo, wi, &lz, &iz)) return;
            *fwd = lambert->pdf(Vec3(0.f, 0.f, lz), Vec3(0.f, 0.f, iz));
            *rev = lambert->pdf(Vec3(0.f, 0.f, iz), Vec3(0.f, 0.f, lz));
            return;
        }
        Vec3 lo, li;
        if (!consistent_sides(wo, wi, &lo, &li)) return;
        std::get<PreviewSurfaceBsdf>(m_model).pdf_pair(lo, li, fwd, rev);
    }
    /// Sample wi given wo; `u2` picks the direction, `u1` the lobe.
    BsdfSample sample(const Vec3& wo, const Vec2& u2, float u1,
                      TransportMode mode = TransportMode::Radiance) const {
        Vec3 lo = m_frame.to_local(wo);
        BsdfSample s = std::visit(
            [&](const auto& m) -> BsdfSample {
                if constexpr (std::is_same_v<std::decay_t<decltype(m)>, PreviewSurfaceBsdf>) {
                    auto ps = m.sample(lo, u1, u2, mode);
                    BsdfSample out;
                    if (!ps) return out;
                    out.wi = ps->wi;
                    out.f = ps->f;
                    out.pdf = ps->pdf;
                    out.is_delta = ps->is_delta;
                    out.is_transmission = ps->is_transmission;
                    out.eta = ps->eta;
                    out.pass_through = ps->pass_through;
                    return out;
                } else {
                    return m.sample(lo, u2, u1);
                }
            },
            m_model);
        if (!s.valid() || !is_finite(s.f)) return BsdfSample();
        bool local_reflect = lo.z * s.wi.z > 0.f;
        s.wi = m_frame.to_world(s.wi);
        float go = dot(wo, m_ng), gi = dot(s.wi, m_ng);
        if (go == 0.f || gi == 0.f) return BsdfSample();
        if ((go * gi > 0.f) != local_reflect) return BsdfSample();
        s.is_transmission = !local_reflect;
        if (local_reflect) s.eta = 1.f;
        return s;
    }
    /// Some lobe is not a Dirac delta: light sampling (NEE) and MIS make sense.
    bool has_non_delta() const {
        return std::visit(
            [](const auto& m) -> bool {
                if constexpr (std::is_same_v<std::decay_t<decltype(m)>, PreviewSurfaceBsdf>)
                    return !m.is_pure_delta();
                else
                    return !m.is_delta();
            },
            m_model);
    }
    /// The pass-through lobe seen from direction wo (world): its weight T and, in *prob,
    /// the probability that `sample` takes it (PreviewSurfaceBsdf::pass_through; 0 for
    /// models without one). A shadow ray crossing the surface is attenuated by T.
    float pass_through(const Vec3& wo, float* prob) const {
        *prob = 0.f;
        if (dot(wo, m_ng) == 0.f) return 0.f;  // as sample(): no side, no crossing
        const float abs_cos = std::fabs(m_frame.to_local(wo).z);
        return std::visit(
            [&](const auto& m) -> float {
                if constexpr (std::is_same_v<std::decay_t<decltype(m)>, PreviewSurfaceBsdf>)
                    return m.pass_through(abs_cos, prob);
                else
                    return 0.f;
            },
            m_model);
    }
    /// Rough reflectance, for AOVs (albedo) and heuristics.
    Spectrum albedo() const {
        return std::visit(
            [](const auto& m) -> Spectrum {
                if constexpr (std::is_same_v<std::decay_t<decltype(m)>, PreviewSurfaceBsdf>)
                    return m.albedo_estimate();
                else
                    return m.albedo();
            },
            m_model);
    }
    const Vec3& shading_normal() const { return m_frame.n; }
    /// The UsdPreviewSurface model, or null for another model.
    const PreviewSurfaceBsdf* preview() const { return std::get_if<PreviewSurfaceBsdf>(&m_model); }
    const Vec3& geometric_normal() const { return m_ng; }

private:
    /// eval (F), pdf (P) or both: the side test, then the model in the local frame.
    template <bool F, bool P>
    Spectrum evaluate(const Vec3& wo, const Vec3& wi, TransportMode mode, float* pdf) const {
        if constexpr (P) *pdf = 0.f;
        if (const auto* lambert = std::get_if<LambertianBsdf>(&m_model)) {
            // Only the cosines enter: the z of the local directions, without the rest of
            // the frame (the same floats as to_local's z).
            float lz, iz;
            if (!consistent_cosines(wo, wi, &lz, &iz)) return Spectrum(0.f);
            if constexpr (P) *pdf = lambert->pdf(Vec3(0.f, 0.f, lz), Vec3(0.f, 0.f, iz));
            return F ? lambert->eval(Vec3(0.f, 0.f, lz), Vec3(0.f, 0.f, iz)) : Spectrum(0.f);
        }
        Vec3 lo, li;
        if (!consistent_sides(wo, wi, &lo, &li)) return Spectrum(0.f);
        const PreviewSurfaceBsdf& preview = std::get<PreviewSurfaceBsdf>(m_model);
        if constexpr (F && P) {
            return preview.eval_pdf(lo, li, mode, pdf);
        } else if constexpr (F) {
            return preview.eval(lo, li, mode);
        } else {
            *pdf = preview.pdf(lo, li);
            return Spectrum(0.f);
        }
    }
    /// consistent_sides for models that read only the local z (cos theta) of wo and wi.
    bool consistent_cosines(const Vec3& wo, const Vec3& wi, float* lz, float* iz) const {
        float go = dot(wo, m_ng), gi = dot(wi, m_ng);
        if (go == 0.f || gi == 0.f) return false;
        *lz = dot(wo, m_frame.n);
        *iz = dot(wi, m_frame.n);
        return (go * gi > 0.f) == (*lz * *iz > 0.f);
    }
    /// Local directions, if the shading-frame side classification of (wo, wi) agrees with
    /// the geometric one (and neither lies in the geometric plane).
    bool consistent_sides(const Vec3& wo, const Vec3& wi, Vec3* lo, Vec3* li) const {
        float go = dot(wo, m_ng), gi = dot(wi, m_ng);
        if (go == 0.f || gi == 0.f) return false;
        *lo = m_frame.to_local(wo);
        *li = m_frame.to_local(wi);
        return (go * gi > 0.f) == (lo->z * li->z > 0.f);
    }

    Model m_model;
    Frame m_frame;
    Vec3 m_ng;
};

}  // namespace cmlt
