#pragma once
/// \file Light interface.
///
/// Conventions: `wi` points from the reference point toward the light; pdfs are per
/// solid angle at the reference point. A Dirac light (point, distant with angle 0)
/// returns `is_delta = true` and pdf 1 with the delta factor folded into `li`.
///
/// Analytic lights are not in the Embree BVH: `intersect` tests them analytically after
/// the BVH query (camera and BSDF rays), and they do not block shadow rays. A light is
/// visible only from its emitting side (UsdLux rect/disk emit toward local -Z);
/// seen from the back it is transparent. Per-sample dispatch is virtual for now (one
/// call per light sample); switch to a variant if a profile says so (STYLE.md §2).
#include "math/mat4.h"
#include "math/ray.h"
#include "math/vec.h"

namespace cmlt {

struct LightSample {
    Vec3 wi;                   ///< unit direction toward the light
    Spectrum li{0.f};          ///< incident radiance (or delta-scaled irradiance)
    float pdf = 0.f;           ///< solid angle (1 for delta lights)
    float dist = k_infinity;   ///< distance to the sampled point (inf for infinite lights)
    Vec3 p_light;              ///< sampled point on the light (finite lights)
    Vec3 n_light;              ///< surface normal at p_light, zero if none (no target offset)
    float error_scale = 0.f;   ///< for offsetting a shadow-ray target on a mesh
    bool is_delta = false;
    bool valid() const { return pdf > 0.f && !is_black(li); }
};

/// Parameters of an analytic light as given by Python (see cmlt/scene.py `Light`).
struct LightDesc {
    enum class Kind { rect, disk, sphere, distant, dome, cylinder };
    Kind kind = Kind::rect;
    Mat4 transform;            ///< light -> world, column-vector convention
    Spectrum radiance{1.f};    ///< intensity * 2^exposure * color (/ area if normalize)
    float width = 1.f, height = 1.f, radius = 0.5f, length = 1.f;
    float angle = 0.53f;       ///< distant: angular diameter, degrees
    bool treat_as_point = false;
};

class Light {
public:
    virtual ~Light() = default;

    virtual LightSample sample_li(const Vec3& p, const Vec2& u) const = 0;
    /// Solid-angle pdf of sampling direction `wi` from `p` (0 for Dirac lights).
    virtual float pdf_li(const Vec3& p, const Vec3& wi) const = 0;
    /// Nearest hit of the emitting side in (ray.tnear, ray.tfar): t and emitted radiance.
    virtual bool intersect(const Ray& /*ray*/, float* /*t*/, Spectrum* /*le*/) const { return false; }
    /// Radiance reaching an escaped ray travelling in direction `d` (infinite lights).
    virtual Spectrum le_escape(const Vec3& /*d*/) const { return Spectrum(0.f); }
    /// Called at commit with the scene bounding sphere (infinite lights need it for power).
    virtual void preprocess(const Vec3& /*center*/, float /*radius*/) {}
    /// Emitted power (luminance), used to build the light-selection distribution.
    virtual float power() const = 0;

    bool is_delta() const { return m_is_delta; }
    bool is_infinite() const { return m_is_infinite; }
    /// Finite analytic emitter tested by `intersect` (rect, disk, sphere).
    bool is_analytic_area() const { return m_is_analytic_area; }

protected:
    bool m_is_delta = false;
    bool m_is_infinite = false;
    bool m_is_analytic_area = false;
};

}  // namespace cmlt
