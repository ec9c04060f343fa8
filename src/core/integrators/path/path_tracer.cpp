#include "integrators/path/path_tracer.h"

#include "cameras/camera.h"
#include "film/filter.h"
#include "integrators/path/path_tracer_impl.h"

namespace cmlt {

Ray PathTracer::camera_ray(const Camera& camera, const PixelFilter& filter, bool motion_blur, PixelSampler& sampler,
                           uint64_t seed, int x, int y, uint32_t pixel, uint32_t s, float* weight,
                           Vec2* p_film_out) const {
    const Vec2 p_film = filter.film_position(x, y, sampler.get2d(), weight);
    if (p_film_out) *p_film_out = p_film;
    Ray ray = camera.generate_ray(p_film);
    if (camera.has_lens()) {  // thin lens: its own dimension
        PixelSampler ls(seed, pixel, s, RngStream::camera_path, m_sequence);
        ls.set_dimension(k_lens_dimension);
        ray = camera.generate_ray(p_film, ls.get2d());
    }
    if (motion_blur) {
        PixelSampler ts(seed, pixel, s, RngStream::camera_path, m_sequence);
        ts.set_dimension(k_shutter_time_dimension);
        ray.time = ts.get1d();
    }
    return ray;
}

Spectrum PathTracer::pixel_sample(const Camera& camera, const PixelFilter& filter, bool motion_blur,
                                  uint64_t seed, int x, int y, uint32_t pixel, uint32_t s,
                                  PathCounters& counters, float* weight, Vec2* p_film) const {
    PixelSampler sampler(seed, pixel, s, RngStream::camera_path, m_sequence);
    const Ray ray = camera_ray(camera, filter, motion_blur, sampler, seed, x, y, pixel, s, weight, p_film);
    return li(ray, sampler, counters);
}

template Spectrum PathTracer::li<PixelSampler>(const Ray&, PixelSampler&, PathCounters&,
                                              const SceneHit*) const;
template void PathTracer::step<PixelSampler>(PathState&, const SceneHit&, PixelSampler&, PathCounters&) const;
template void PathTracer::step<PixelSampler>(PathState&, const LambertHit&, PixelSampler&, PathCounters&) const;
template void PathTracer::step<PixelSampler>(PathState&, const BsdfHit&, PixelSampler&, PathCounters&) const;

}  // namespace cmlt
