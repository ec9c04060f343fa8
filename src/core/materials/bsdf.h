#pragma once
/// \file The BSDF at a surface point: a lobe model in its local shading frame.
///
/// `Bsdf` is a value type (no heap allocation per hit) holding a std::variant of lobe
/// models; the integrator calls eval / pdf / sample in world space and never sees the
/// model. New models (GGX, dielectric, clearcoat with Dirac lobes) become new variant
/// alternatives; `is_delta` on samples and `has_non_delta()` tell the integrator when
/// light sampling and MIS apply.
///
/// Reflection is accepted only when wo and wi lie on the same side of the *geometric*
/// normal too (no light leaks through shading normals).
#include "materials/bsdf_sample.h"
#include "materials/lambertian.h"
#include "materials/material.h"
#include "math/frame.h"

#include <variant>

namespace cmlt {

class Bsdf {
public:
    using Model = std::variant<LambertianBsdf>;

    Bsdf(const Model& model, const Vec3& ns, const Vec3& ng)
        : m_model(model), m_frame(ns), m_ng(ng) {}

    static Bsdf from_material(const Material& mat, const Vec3& ns, const Vec3& ng) {
        return Bsdf(LambertianBsdf(mat.diffuse), ns, ng);
    }

    Spectrum eval(const Vec3& wo, const Vec3& wi) const {
        if (dot(wo, m_ng) * dot(wi, m_ng) <= 0.f) return Spectrum(0.f);
        Vec3 lo = m_frame.to_local(wo), li = m_frame.to_local(wi);
        return std::visit([&](const auto& m) { return m.eval(lo, li); }, m_model);
    }
    float pdf(const Vec3& wo, const Vec3& wi) const {
        if (dot(wo, m_ng) * dot(wi, m_ng) <= 0.f) return 0.f;
        Vec3 lo = m_frame.to_local(wo), li = m_frame.to_local(wi);
        return std::visit([&](const auto& m) { return m.pdf(lo, li); }, m_model);
    }
    /// Sample wi given wo; `u2` picks the direction, `u1` the lobe.
    BsdfSample sample(const Vec3& wo, const Vec2& u2, float u1) const {
        Vec3 lo = m_frame.to_local(wo);
        BsdfSample s = std::visit([&](const auto& m) { return m.sample(lo, u2, u1); }, m_model);
        if (!s.valid()) return BsdfSample();
        s.wi = m_frame.to_world(s.wi);
        if (dot(wo, m_ng) * dot(s.wi, m_ng) <= 0.f) return BsdfSample();
        return s;
    }
    bool has_non_delta() const {
        return std::visit([](const auto& m) { return !m.is_delta(); }, m_model);
    }
    const Vec3& shading_normal() const { return m_frame.n; }

private:
    Model m_model;
    Frame m_frame;
    Vec3 m_ng;
};

}  // namespace cmlt
