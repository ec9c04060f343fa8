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
#include "base/sampler.h"
#include "integrators/common/path_counters.h"
#include "math/ray.h"
#include "math/vec.h"
#include "sampling/rng.h"

#include <cstdint>

namespace cmlt {

class Camera;
class PixelFilter;
class Scene;
struct SceneHit;

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

    /// One independent pixel sample of pixel (x, y), sample index `s`: film position
    /// (dimension 0: the pixel's centre + an offset drawn from `filter`, whose f/pdf goes
    /// to *weight for the film; PixelFilter::film_position), lens (k_lens_dimension, with a thin lens), shutter time
    /// (k_shutter_time_dimension, when `motion_blur`), then li — the numbers keyed by
    /// (seed, pixel, s) through PixelSampler.
    Spectrum pixel_sample(const Camera& camera, const PixelFilter& filter, bool motion_blur, uint64_t seed,
                          int x, int y, int width, uint32_t s, PathCounters& counters, float* weight) const;

private:
    const Scene& m_scene;
    int m_max_depth;
    int m_min_depth;
};

extern template Spectrum PathTracer::li<PixelSampler>(const Ray&, PixelSampler&,
                                                     PathCounters&, const SceneHit*) const;

}  // namespace cmlt
