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

#include <cstdint>

namespace cmlt {

class Texture;

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

/// A ray leaving a finite light (light tracing, BDPT): origin on the light, direction,
/// and the densities that generated them.
struct LightLeSample {
    Vec3 p;                  ///< origin on the light
    Vec3 n;                  ///< unit normal of the emitting side at p (zero for a point light)
    Vec3 d;                  ///< unit emission direction
    Spectrum le{0.f};        ///< radiance leaving p along d (intensity for a point light)
    float pdf_pos = 0.f;     ///< area density of p (1 for a point light: Dirac position)
    float pdf_dir = 0.f;     ///< solid-angle density of d given p
    float error_scale = 0.f; ///< for offsetting rays leaving p
    /// Positive densities. `le` may be black (a shaped light outside its cone, a black
    /// texel): the light subpath must still start, or BDPT would lose its s = 1
    /// strategy (which resamples the light with sample_li) for that sample -- a bias.
    bool valid() const { return pdf_pos > 0.f && pdf_dir > 0.f; }
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
    /// UsdLux ShapingAPI (rect, disk, sphere, cylinder; lights/shaping.h): cone half-angle
    /// about local -Z in degrees (180: none), cone softness in [0, 1], focus exponent
    /// (0: none) and focus tint.
    float cone_angle = 180.f, cone_softness = 0.f, focus = 0.f;
    Spectrum focus_tint{0.f};
    /// Texture id (Scene::add_texture) or -1: dome (lat-long, lights/dome_light.h) and
    /// rect (lights/area_lights.h) multiply their radiance by it.
    int32_t texture_id = -1;
};

/// What a rect light's sample_li computes its sample from, for many shading points at
/// once (Light::rect_constants; integrators/path/diffuse_lanes.h, rect_light_samples).
struct RectLightConstants {
    double m[3][4] = {};   ///< object to world, the affine rows (Transform::m)
    float w = 0.f, h = 0.f;  ///< extents along local x and y
    Vec3 n_emit;           ///< unit world normal of the emitting side
    float area = 0.f;      ///< world area
    Spectrum radiance;     ///< what sample_li returns as li
};

/// What a sphere light's sample_li computes its sample from, for many shading points at
/// once (Light::sphere_constants; integrators/path/diffuse_lanes.h, sphere_light_samples).
struct SphereLightConstants {
    Vec3 center;
    float radius = 0.f;
    Spectrum radiance;  ///< what sample_li returns as li
};

class Light {
public:
    virtual ~Light() = default;

    /// True, with `*out`, for a light whose sample_li is RectLightConstants' rect sample
    /// exactly: an untextured rect light without shaping, of positive area and non-black
    /// radiance (RectLight). False for every other light.
    virtual bool rect_constants(RectLightConstants* /*out*/) const { return false; }
    /// True, with `*out`, for a light whose sample_li is SphereLightConstants' cone sample
    /// exactly: a sphere light (not treated as a point) without shaping, of positive radius
    /// and non-black radiance (SphereLight). False for every other light.
    virtual bool sphere_constants(SphereLightConstants* /*out*/) const { return false; }

    virtual LightSample sample_li(const Vec3& p, const Vec2& u) const = 0;
    /// Solid-angle pdf of sampling direction `wi` from `p` (0 for Dirac lights).
    virtual float pdf_li(const Vec3& p, const Vec3& wi) const = 0;
    /// Nearest hit of the emitting side in (ray.tnear, ray.tfar): t and emitted radiance.
    virtual bool intersect(const Ray& /*ray*/, float* /*t*/, Spectrum* /*le*/) const { return false; }
    /// A world-space sphere containing everything `intersect` can hit (analytic area
    /// lights): the scene skips `intersect` for rays that cannot come near it
    /// (Scene::resolve_hit). False: no bound, always test.
    virtual bool bounding_sphere(Vec3* /*center*/, float* /*radius*/) const { return false; }
    /// A world-space box containing everything `intersect` can hit (lower, upper); by
    /// default the bounding sphere's. False: no bound.
    virtual bool bounding_box(Vec3* lo, Vec3* hi) const {
        Vec3 c;
        float r;
        if (!bounding_sphere(&c, &r)) return false;
        *lo = c - Vec3(r);
        *hi = c + Vec3(r);
        return true;
    }
    /// Radiance reaching an escaped ray travelling in direction `d` (infinite lights).
    virtual Spectrum le_escape(const Vec3& /*d*/) const { return Spectrum(0.f); }
    /// le_escape(d) and, where `pdf` is not null, pdf_li(p, d) into it: a light whose two
    /// share work (the dome's direction to texture coordinates) does it once.
    virtual Spectrum le_escape_pdf(const Vec3& d, const Vec3& p, float* pdf) const {
        if (pdf) *pdf = pdf_li(p, d);
        return le_escape(d);
    }
    /// Called at commit with the scene bounding sphere (infinite lights need it for power).
    virtual void preprocess(const Vec3& /*center*/, float /*radius*/) {}
    /// Emitted power (luminance), used to build the light-selection distribution.
    virtual float power() const = 0;

    // Emission sampling for light tracing (BDPT, MLT). Finite lights only: infinite lights
    // are sampled from sample_li / pdf_li (direction) and a disk covering the scene
    // (integrators/bdpt/light_emission.h). Implementations: lights/light_emission.cpp.
    /// Sample an emitted ray: `u_pos` picks the point, `u_dir` the direction.
    virtual LightLeSample sample_le(const Vec2& /*u_pos*/, const Vec2& /*u_dir*/) const {
        return LightLeSample();
    }
    /// Densities of emitting from point `p` (on the light) along unit direction `d`.
    virtual void pdf_le(const Vec3& /*p*/, const Vec3& /*d*/, float* pdf_pos, float* pdf_dir) const {
        *pdf_pos = *pdf_dir = 0.f;
    }
    /// Unit normal of the emitting side at a point on the light (zero for a point light).
    virtual Vec3 emitter_normal(const Vec3& /*p*/) const { return Vec3(0.f); }
    /// Radiance leaving the point `p` on the light along the unit direction `d` (0 where
    /// `d` leaves the back of a one-sided emitter): what a camera ray arriving at `p`
    /// from `-d` sees, texture and shaping included. BDPT's (1, 1) strategy (a light
    /// point connected to the lens) needs it; a light without it (the default: false)
    /// keeps that strategy off, and the camera's own hits carry its whole weight.
    virtual bool le_toward(const Vec3& /*p*/, const Vec3& /*d*/, Spectrum* /*le*/) const {
        return false;
    }

    /// Texture this light was created with (LightDesc::texture_id), or -1.
    int32_t texture_id() const { return m_texture_id; }
    /// Called at commit (before preprocess) with the scene's texture `texture_id()`; the
    /// texture outlives the light's use until the next commit.
    virtual void bind_texture(const Texture* /*tex*/) {}

    bool is_delta() const { return m_is_delta; }
    bool is_infinite() const { return m_is_infinite; }
    /// Finite analytic emitter tested by `intersect` (rect, disk, sphere, cylinder).
    bool is_analytic_area() const { return m_is_analytic_area; }

protected:
    bool m_is_delta = false;
    bool m_is_infinite = false;
    bool m_is_analytic_area = false;
    int32_t m_texture_id = -1;
};

}  // namespace cmlt
