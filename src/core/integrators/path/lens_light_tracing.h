#pragma once
/// \file BDPT's (1, 1) strategy for a path-traced pass: a point sampled on a light,
/// connected to the lens and splatted where it lands, MIS-weighted against the camera
/// rays that hit the same light. The pt integrator (path_integrator.cpp) and the
/// Metropolis direct pass (mlt/direct_pass.h) use it for lights smaller than a pixel,
/// which camera rays almost never hit: a 0.4 mm bulb seen directly covers 2e-5 of its
/// pixel, so a render either misses a third of the image or, once in ~50,000 samples,
/// hits it with a weight of L/spp (sequences/hard/bulb_room).
///
/// Which lights: the analytic lights (sphere, rect, disk, cylinder) whose bounding
/// sphere projects to less than a pixel across (`k_max_pixels`), centre inside the
/// film window. Only they take part, sampled by power among themselves; every other
/// light's camera hits keep weight 1, and a scene with none renders exactly as without
/// this class (active() false).
///
/// Weights (power heuristic over the two strategies of a depth-0 path from lens point
/// p_lens to light point x with normal n): p_cam = the camera's solid-angle density of
/// the direction (CameraImportance::pdf_dir) · |cos_x| / d², p_light = the light's pmf
/// among the traced lights · its area density at x; camera hit w = p_cam² / (p_cam² +
/// p_light²), light sample 1 - w. Both sides compute the same function of the path, so
/// the weights sum to 1 whatever the film sampling (the camera density is the whole
/// window's, as in BDPT, where one light sample per pixel sample makes it the right
/// ratio).
///
/// One light sample per pixel sample, keyed (seed, pixel, sample index) in its own
/// stream (RngStream::lens_light): a splat of value Le(x → lens) |cos_x| We cos_cam /
/// (pmf pdf_pos d² pdf_lens) · w, which over the W·H samples of a pass estimates the
/// image's (1, 1) share (times window / image area, as bdpt's splats).
#include "cameras/camera.h"
#include "integrators/bdpt/camera_importance.h"
#include "integrators/common/frame_loop.h"
#include "math/vec.h"
#include "sampling/discrete_distribution.h"

#include <tbb/task_arena.h>

#include <cstdint>
#include <utility>
#include <vector>

namespace cmlt {

class CausticLightTracing;
class PixelFilter;
class Scene;

class LensLightTracing {
public:
    /// A light is traced when its bounding sphere is less than this many pixels across.
    static constexpr float k_max_pixels = 1.f;

    /// `margin`: the film window's (PixelFilter::margin).
    LensLightTracing(const Scene& scene, const Camera& camera, int width, int height, float margin);
    /// The lights traced (file comment): analytic, not Dirac, bounding sphere less than
    /// k_max_pixels across on the film, centre inside the window. Also the lights of
    /// the bdpt integrator's (1, 1) strategy.
    static std::vector<uint32_t> sub_pixel_lights(const Scene& scene, const Camera& camera, int width,
                                                  int height, float margin);
    /// Some light is traced.
    bool active() const { return !m_lights.empty(); }
    /// Lights traced (indices into Scene::light).
    const std::vector<uint32_t>& lights() const { return m_lights; }

    /// MIS weight of a camera ray from `p_lens` that hits light `light_index` at `p`
    /// (1 for a light not traced).
    float camera_hit_weight(const Vec3& p_lens, const Vec3& p, uint32_t light_index) const;

    /// The light sample keyed (seed, pixel, sample): false if it makes no contribution,
    /// else its weighted value and raster position. `shadow_rays` counts the connection.
    bool sample(uint64_t seed, uint32_t pixel, uint32_t sample, bool motion_blur, Vec2* p_raster,
                Spectrum* value, uint64_t* shadow_rays) const;

private:
    /// The camera's power-heuristic weight p_cam² / (p_cam² + p_light²) of the path
    /// (p_lens, p on light `slot`): the light sample's is 1 minus it, so the two sum to 1.
    float camera_share(const Vec3& p_lens, const Vec3& p, uint32_t slot) const;
    /// p_cam and p_light of the path (p_lens, p on light `slot`).
    void densities(const Vec3& p_lens, const Vec3& p, uint32_t slot, float* p_cam, float* p_light) const;

    const Scene& m_scene;
    CameraImportance m_importance;
    std::vector<uint32_t> m_lights;  ///< traced lights
    std::vector<int32_t> m_slot;     ///< Scene light index -> index into m_lights, or -1
    DiscreteDistribution m_dist;     ///< over m_lights, by power
};

/// The light samples of one pass over the whole frame (one per pixel), splatted through
/// the film's filter: the `extra` image of PassSplatter::gather. The samples are traced
/// in parallel by rows and splatted in row order, so the sums do not depend on the
/// thread count; a part of the frame gets the whole frame's splats (its rows receive
/// light from every pixel's sample). Each pixel's sample is the lens light sample (when
/// `lens` is active) and the caustic light path (when `caustic` is given and active;
/// caustic_light_tracing.h).
class LensPass {
public:
    LensPass(const LensLightTracing& lens, const PixelFilter& filter, int width, int height,
             const CausticLightTracing* caustic = nullptr);
    /// Pass `sample`'s splats, W x H x 3 (valid until the next call). Counts the
    /// connections as shadow rays and rays.
    const double* trace(tbb::task_arena& arena, FrameCounters& counters, uint64_t seed, uint32_t sample,
                        bool motion_blur);

private:
    const LensLightTracing& m_lens;
    const CausticLightTracing* m_caustic;
    const PixelFilter& m_filter;
    int m_width, m_height;
    double m_scale;  ///< the window's area over the image's: importance is normalised over the window
    std::vector<std::vector<std::pair<Vec2, Spectrum>>> m_rows;
    std::vector<double> m_image;
};

}  // namespace cmlt
