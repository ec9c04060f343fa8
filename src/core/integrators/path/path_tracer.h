#pragma once
/// \file Unidirectional path tracing with next-event estimation and MIS.
///
/// Estimates the measurement of one camera ray (Veach 1997 ch. 9, power heuristic with
/// beta = 2, one light sample and one BSDF sample per vertex), following pbrt-v4's
/// PathIntegrator::Li:
///  * emission found by BSDF-sampled rays (emissive triangles, analytic area lights,
///    dome / distant-cone on escape) is weighted against light sampling;
///  * light samples are weighted against BSDF sampling; Dirac lights and Dirac BSDF
///    lobes get weight 1 from their only strategy;
///  * `max_depth` counts scattering events: 1 = direct lighting only;
///  * Russian roulette from the 4th scattering event on, continuation probability
///    min(0.95, max(beta)), its random number at a fixed dimension.
///
/// Random dimensions: 0 = film position; bounce b uses [1 + 5b, 1 + 5b + 5):
/// light choice, light position (2D), BSDF direction (2D), BSDF lobe, roulette. Bounces
/// count hits: a pass-through crossing (cut-out, ior-1 interface; not a scattering event,
/// so not counted in max_depth) has its own bounce, whose lobe number decides it.
///
/// Shadow rays use Scene::transmittance: they cross pass-through surfaces as BSDF-sampled
/// rays do, and the MIS weights include the crossings' selection probabilities.
///
/// `li` is generic over its random source, a PathSampler (base/sampler.h), so the same
/// sampling routine runs on independent numbers (PixelSampler) or on a Markov chain's
/// primary samples (mlt::MltSampler, coherent::PointSampler). The definition is in
/// path_tracer_impl.h; path_tracer.cpp instantiates PixelSampler.
///
/// The routine is resumable (PathState): `begin` starts a path at a camera ray, `step`
/// takes the hit of the current ray and leaves the path's next ray and, when next-event
/// estimation wants one, a shadow ray; `finish_shadow` takes that shadow ray's
/// visibility. `li` runs it with one scalar query at a time; the batched path tracer
/// (path_batch.h) runs many paths in lockstep and answers their queries in Embree
/// packets — the same arithmetic on the same answers, so the same estimator.
#include "base/sampler.h"
#include "integrators/common/path_counters.h"
#include "integrators/common/path_partition.h"
#include "math/ray.h"
#include "math/vec.h"
#include "sampling/mis.h"
#include "sampling/rng.h"

#include <cstdint>

namespace cmlt {

class Bsdf;
class Camera;
class CausticLightTracing;
class LensLightTracing;
class PixelFilter;
class Scene;
struct HitGeometry;
class Bsdf;
struct SceneHit;
struct SurfacePoint;

/// A surface hit whose material is a constant Lambertian (Scene::constant_lambert):
/// what the path tracer's diffuse fast path shades (PathBatch), the same path as
/// step(SceneHit) on the full hit.
struct LambertHit {
    const HitGeometry* geometry;
    const Spectrum* reflectance;
};

/// A surface hit placed in PathBatch's lanes with its BSDF already made (a constant
/// preview BSDF, Scene::constant_preview, or make_bsdf_at for Scene::lane_material): the
/// material emits nothing and lets no ray through, and step(BsdfHit) takes the same path
/// as step(SceneHit) on the full hit.
struct BsdfHit {
    const HitGeometry* geometry;
    const Bsdf* bsdf;
};

/// One path of PathTracer between two ray queries (path_tracer.h).
struct PathState {
    Spectrum L{0.f}, beta{1.f};
    Ray ray;                    ///< the ray whose hit `step` takes next
    Vec3 prev_p;                ///< the last scattering vertex (MIS of emission hits)
    float prev_bsdf_pdf = 0.f;  ///< BSDF density of `ray` (times crossed pass-through probabilities)
    float eta_scale = 1.f;      ///< product of eta^2 over refractions: undoes radiance scaling for RR
    uint32_t bounce = 0;        ///< hits so far, pass-through crossings included (keys the dimensions)
    int depth = 0;              ///< scattering events so far
    bool specular_bounce = false;
    bool done = false;
    /// The path's class (integrators/common/path_partition.h), kept only when the
    /// tracer has a partition: a rough vertex among the scattering vertices so far, one
    /// before the last of them, and the last one's material near-specular.
    bool diffuse_seen = false, diffuse_before_last = false, last_specular = false;
    bool first_specular = false;  ///< x1's material near-specular
    bool first_dirac = false;     ///< x1 scattered by a Dirac lobe (the light-traced caustics)
    uint8_t n_diffuse = 0;        ///< rough scattering vertices so far (saturating at 2)

    /// Does `partition` want the path so far continued by a vertex whose material is
    /// `specular` and ending on a light there (next-event estimation from that vertex)?
    bool wants_next_event(const PathPartition& partition, bool specular) const {
        return partition.wants(partition.caustic(specular, diffuse_seen, depth == 0 ? specular : first_specular,
                                                 n_diffuse + (specular ? 0 : 1)));
    }
    /// With caustic light tracing (caustic_light_tracing.h): the camera side of r so far,
    /// 1 / (p_cam(z1) Π p⊥ forward) times the light side's reverse factors; 0 when the
    /// path cannot be of the class (z1 scattered by a Dirac lobe) or no tracer is set.
    double lt = 0.0;
    /// Next-event estimation pending on a shadow ray: if `shadow` is unblocked (through
    /// pass-through surfaces with transmittance tr and crossing probability pass_pdf),
    /// L += shadow_f * (tr * w / shadow_light_pdf), w the power heuristic of
    /// shadow_light_pdf against shadow_bsdf_pdf * pass_pdf (1 for a Dirac light).
    bool has_shadow = false;
    uint32_t shadow_light = 0;  ///< the light `shadow` aims at (Scene::blocked_by_light(ray, target))
    bool shadow_delta = false;
    Ray shadow;
    Spectrum shadow_f{0.f};
    float shadow_light_pdf = 0.f, shadow_bsdf_pdf = 0.f;
};

class PathTracer {
public:
    static constexpr uint32_t k_dims_per_bounce = 5;
    static constexpr int k_rr_start_depth = 3;

    /// Paths of `min_depth` ≤ depth ≤ `max_depth` scattering events (min_depth 0: all;
    /// the Metropolis integrators leave depths below 2 to their direct pass).
    PathTracer(const Scene& scene, int max_depth, int min_depth = 0)
        : m_scene(scene), m_max_depth(max_depth), m_min_depth(min_depth) {}

    /// Radiance along a camera ray (may be non-finite only through a bug; the film checks).
    /// `first_hit`, if given, is what `camera_ray` hits first (Scene::intersect's answer,
    /// e.g. from a packet query: integrators/cmlt); it is used instead of tracing the
    /// camera ray again. The camera ray is still counted in the counters.
    template <class Sampler>
    Spectrum li(const Ray& camera_ray, Sampler& sampler, PathCounters& counters,
                const SceneHit* first_hit = nullptr) const;

    /// Camera hits at depth 0 on the lights `lens` traces share those paths with its
    /// (1, 1) light samples: their emission gets its MIS weight (the Metropolis direct
    /// pass; lens_light_tracing.h). Null (the default): weight 1.
    void set_lens_light_tracing(const LensLightTracing* lens) { m_lens_light = lens; }
    /// Emission reached from a rough first vertex through a Dirac last bounce shares
    /// those paths with `caustic`'s light paths (the pt integrator;
    /// caustic_light_tracing.h). Null (the default): weight 1.
    void set_caustic_light_tracing(const CausticLightTracing* caustic) { m_caustic = caustic; }
    /// Render only the paths of one class (path_partition.h): the Metropolis
    /// integrators' direct pass the easy ones, their pt path sampler the caustic ones.
    /// Null or PathPart::all (the default): every path.
    void set_partition(const PathPartition* partition) {
        m_partition = PathPartition::restricting(partition);
    }

    /// The numbers of the pixel samples this tracer starts (pixel_sample, camera_ray,
    /// PathBatch): independent (the default) or Owen-scrambled Sobol
    /// (RenderSettings::sampler).
    void set_sequence(PixelSequence sequence) { m_sequence = sequence; }
    PixelSequence sequence() const { return m_sequence; }

    int max_depth() const { return m_max_depth; }
    int min_depth() const { return m_min_depth; }
    /// What PathBatch's diffuse lanes (diffuse_lanes.h) follow as scatter does: the
    /// partition (next-event estimation only for the paths it wants) and caustic light
    /// tracing (PathState::lt).
    const PathPartition* partition() const { return m_partition; }
    const CausticLightTracing* caustic_light_tracing() const { return m_caustic; }

    /// Start a path at `camera_ray` (counted as a sample and a camera ray).
    void begin(PathState& st, const Ray& camera_ray, PathCounters& counters) const;
    /// Take `hit`, the answer to st.ray (counted as a ray): add what it sees, and leave
    /// st.done or the next st.ray, and st.has_shadow with a pending shadow ray.
    template <class Sampler>
    void step(PathState& st, const SceneHit& hit, Sampler& sampler, PathCounters& counters) const;
    /// step() for a constant-Lambertian surface hit, from its geometry alone.
    template <class Sampler>
    void step(PathState& st, const LambertHit& hit, Sampler& sampler, PathCounters& counters) const;
    /// step() for a surface hit whose BSDF is made (BsdfHit), from its geometry alone.
    template <class Sampler>
    void step(PathState& st, const BsdfHit& hit, Sampler& sampler, PathCounters& counters) const;
    /// Complete a pending shadow ray: `tr` and `pass_pdf` as Scene::transmittance gives them.
    static void finish_shadow(PathState& st, float tr, float pass_pdf) {
        st.has_shadow = false;
        if (!(tr > 0.f)) return;
        st.L += st.shadow_f * (tr * shadow_weight(st, pass_pdf) / st.shadow_light_pdf);
    }
    /// The MIS weight of a pending shadow ray's light sample: 1 toward a Dirac light, else
    /// the power heuristic against the BSDF's density times the crossings' `pass_pdf`.
    static float shadow_weight(const PathState& st, float pass_pdf) {
        return st.shadow_delta ? 1.f : power_heuristic(st.shadow_light_pdf, st.shadow_bsdf_pdf * pass_pdf);
    }
    /// finish_shadow(st, visible ? 1 : 0, 1) without a branch on `visible` (whether a
    /// shadow ray is blocked is no pattern a predictor learns): the same floats.
    static void finish_shadow_visible(PathState& st, bool visible) {
        st.has_shadow = false;
        const Spectrum add = st.shadow_f * (1.f * shadow_weight(st, 1.f) / st.shadow_light_pdf);
        st.L.x = visible ? st.L.x + add.x : st.L.x;
        st.L.y = visible ? st.L.y + add.y : st.L.y;
        st.L.z = visible ? st.L.z + add.z : st.L.z;
    }

    /// The camera ray of pixel (x, y), sample `s`, its numbers keyed by `pixel` (y W + x
    /// in the image; PassSplatter::window_key beyond it): film position (dimension 0,
    /// from `filter`, whose f/pdf goes to *weight; the position to *p_film if given),
    /// lens and shutter time (pixel_sample).
    Ray camera_ray(const Camera& camera, const PixelFilter& filter, bool motion_blur, PixelSampler& sampler,
                   uint64_t seed, int x, int y, uint32_t pixel, uint32_t s, float* weight,
                   Vec2* p_film = nullptr) const;

    /// One independent pixel sample of pixel (x, y), sample index `s`: film position
    /// (dimension 0: the pixel's centre + an offset drawn from `filter`, whose f/pdf goes
    /// to *weight for the film; PixelFilter::film_position), lens (k_lens_dimension, with a thin lens), shutter time
    /// (k_shutter_time_dimension, when `motion_blur`), then li — the numbers keyed by
    /// (seed, pixel, s) through PixelSampler (`pixel` as in camera_ray).
    Spectrum pixel_sample(const Camera& camera, const PixelFilter& filter, bool motion_blur, uint64_t seed,
                          int x, int y, uint32_t pixel, uint32_t s, PathCounters& counters, float* weight,
                          Vec2* p_film = nullptr) const;

private:
    /// A hit on an opaque, non-emitting surface (step(LambertHit), step(BsdfHit)): counts
    /// the bounce (its index in *bounce) and the ray; false if the path ends there.
    bool enter_opaque_hit(PathState& st, PathCounters& counters, uint32_t* bounce) const;
    /// The scattering part of step at a surface point: next-event estimation, BSDF
    /// sampling, Russian roulette. `passes`: the material may let the ray through;
    /// `last`: the path has its max_depth scattering events (only a crossing goes on).
    template <class Sampler>
    /// `specular`: the vertex's material is a specular one of the partition.
    void scatter(PathState& st, uint32_t bounce, const SurfacePoint& sp, const Vec3& wo, const Bsdf& bsdf,
                 bool passes, bool last, bool specular, Sampler& sampler, PathCounters& counters) const;

    const Scene& m_scene;
    int m_max_depth;
    int m_min_depth;
    const LensLightTracing* m_lens_light = nullptr;
    const CausticLightTracing* m_caustic = nullptr;
    const PathPartition* m_partition = nullptr;
    PixelSequence m_sequence = PixelSequence::independent;
};

extern template Spectrum PathTracer::li<PixelSampler>(const Ray&, PixelSampler&,
                                                     PathCounters&, const SceneHit*) const;
extern template void PathTracer::step<PixelSampler>(PathState&, const SceneHit&, PixelSampler&,
                                                    PathCounters&) const;
extern template void PathTracer::step<PixelSampler>(PathState&, const LambertHit&, PixelSampler&,
                                                    PathCounters&) const;
extern template void PathTracer::step<PixelSampler>(PathState&, const BsdfHit&, PixelSampler&,
                                                    PathCounters&) const;

}  // namespace cmlt
