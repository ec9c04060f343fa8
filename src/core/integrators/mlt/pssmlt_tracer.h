#pragma once
/// \file Per-chain path work of PSSMLT: turn the sampler's current primary samples into a
/// path sample (film position, contribution, f*).
///
/// Dimension layout (camera stream): dimension 0 = film position over the whole image,
/// then the path tracer's own layout (path_tracer.h: bounce b uses 1 + 5b ..). The path
/// is sampled by PathTracer::li (NEE + MIS), so f* is the luminance of PT's estimator
/// for that film position; PSSMLT then redistributes PT's samples by f*. Multiplexing
/// over BDPT strategies (DESIGN.md §2) replaces `li` by the strategy evaluation, on the
/// light and connection streams of the same sampler.
#include "cameras/camera.h"
#include "integrators/mlt/mlt_sampler.h"
#include "integrators/path/path_tracer.h"

#include <algorithm>
#include <cstdint>

namespace cmlt::mlt {

/// One evaluated state of a chain: where it splats and what.
struct PathSample {
    uint32_t pixel = 0;  ///< y·W + x
    Spectrum L{0.f};     ///< contribution (PT estimate for the sampled film position)
    double f = 0.0;      ///< f* = luminance(L) in the rendering space, ≥ 0
    bool invalid = false;  ///< L was not finite (f = 0, never splatted)
};

class PssmltTracer {
public:
    PssmltTracer(const PathTracer& tracer, const Camera& camera, int width, int height)
        : m_tracer(tracer), m_camera(camera), m_width(width), m_height(height) {}

    /// The camera ray of the sampler's current proposal (camera stream, dimension 0 =
    /// film position) and its pixel. Leaves the sampler on the camera stream after the
    /// film position, where evaluate's path sampling continues.
    template <class Sampler>
    Ray camera_ray(Sampler& sampler, uint32_t* pixel) const {
        sampler.start_stream(MltSampler::camera);
        sampler.set_dimension(0);
        const Vec2 u = sampler.get2d();
        const Vec2 p_raster(u.x * float(m_width), u.y * float(m_height));
        const int x = std::min(int(p_raster.x), m_width - 1);
        const int y = std::min(int(p_raster.y), m_height - 1);
        *pixel = uint32_t(y) * uint32_t(m_width) + uint32_t(x);
        return m_camera.generate_ray(p_raster);
    }

    /// Evaluate the sampler's current proposal. `Sampler`: MltSampler (or any sampler
    /// with start_stream + the path_tracer.h interface). `first_hit`, if given, is what
    /// camera_ray(sampler) hits first (coherent MLT traces the camera rays of a bundle
    /// as one Embree packet, integrators/cmlt): the camera ray is then not traced again.
    template <class Sampler>
    PathSample evaluate(Sampler& sampler, PathCounters& counters,
                        const SceneHit* first_hit = nullptr) const {
        PathSample s;
        const Ray ray = camera_ray(sampler, &s.pixel);
        s.L = m_tracer.li(ray, sampler, counters, first_hit);
        if (!is_finite(s.L)) {
            s.invalid = true;
            s.L = Spectrum(0.f);
            return s;
        }
        s.f = target_luminance(s.L);
        return s;
    }

    int width() const { return m_width; }
    int height() const { return m_height; }

private:
    const PathTracer& m_tracer;
    const Camera& m_camera;
    int m_width, m_height;
};

}  // namespace cmlt::mlt
