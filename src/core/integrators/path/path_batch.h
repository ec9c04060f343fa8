#pragma once
/// \file Path tracing in batches: the paths of one tile's pixel samples run in lockstep,
/// and each round's ray queries — the closest hits of every live path, then the shadow
/// rays of their next-event estimation — are answered together in Embree packets
/// (Accel::intersect_lanes / occluded_lanes: rtcIntersect4/8/16, rtcOccluded4/8/16).
///
/// Each path is PathTracer's resumable routine (PathState: begin / step /
/// finish_shadow), so a lane computes what PathTracer::li computes from the same
/// answers; without packets (RenderSettings::packets off) every query is a scalar one
/// and the image is li's bit for bit. Embree's packet and single-ray kernels may differ
/// in the last ulp of a hit, so with packets the image is the same estimator, not the
/// same bits (tests/cpp/integrators: the two agree within their confidence intervals).
///
/// Lanes are the pixels of a tile in 4×4 blocks, so that a packet's camera rays (and
/// the first bounces' shadow rays toward a light) are neighbours; a lane whose path ends
/// leaves the batch (the live lanes stay in that order), so packets stay full.
/// Everything a lane computes depends only on its (seed, pixel, sample), never on the
/// packets it shared: the image does not depend on the thread count.
#include "film/pass_splatter.h"
#include "integrators/common/frame_loop.h"
#include "integrators/path/diffuse_lanes.h"
#include "integrators/path/path_tracer.h"
#include "materials/preview_surface.h"
#include "sampling/rng.h"

#include <cstdint>
#include <memory>
#include <vector>

namespace cmlt {

class Camera;
class Film;
class PixelFilter;
class Scene;
struct Hit;

class PathBatch {
public:
    /// `packet_width` 4, 8 or 16 answers queries in packets of up to that width; 1 one
    /// by one. Pixels are keyed PassSplatter::window_key(x, y, width, height, reach, shift):
    /// tiles may reach `reach` pixels beyond the W x H image (a splatting film's ring).
    PathBatch(const PathTracer& tracer, const Scene& scene, const Camera& camera, const PixelFilter& filter,
              bool motion_blur, uint64_t seed, int width, int height, int reach, int packet_width,
              KeyShift shift = {});

    /// Sample `s` of every pixel of `tile`: L[i] and the filter weight w[i] of the i-th
    /// pixel of the tile in row-major order, and its film position p[i] if p is given.
    void trace_tile(const Tile& tile, uint32_t s, PathCounters& counters, Spectrum* L, float* w,
                    Vec2* p = nullptr);

    /// trace_tile, each pixel's sample then added to `film` (Film::add_sample).
    void trace_tile_to(const Tile& tile, uint32_t s, PathCounters& counters, Film& film);
    /// trace_tile, each pixel's sample then set in `splatter` at its film position
    /// (PassSplatter::set; the batch's filter is the unit box).
    void trace_tile_to(const Tile& tile, uint32_t s, PathCounters& counters, PassSplatter& splatter);

    uint64_t packets() const { return m_packets; }
    /// Hits shaded in the diffuse lanes so far (a path at its last vertex included).
    uint64_t lane_hits() const { return m_lane_hits; }

    /// Shade constant-Lambertian hits in structure-of-arrays lanes (diffuse_lanes.h; the
    /// default) or one lane at a time through PathTracer::step(LambertHit): the same
    /// floats either way (tests/cpp).
    void set_diffuse_lanes(bool on) { m_use_lanes = on; }

private:
    const PathTracer& m_tracer;
    const Scene& m_scene;
    const Camera& m_camera;
    const PixelFilter& m_filter;
    bool m_motion_blur;
    // a perspective camera without lens or shutter time: its rays in lanes (camera_directions)
    bool m_pinhole_lanes = false;
    PinholeConstants m_pinhole;
    uint64_t m_seed;
    int m_width, m_height, m_reach;
    KeyShift m_shift;
    int m_packet_width;
    uint64_t m_packets = 0;
    uint64_t m_lane_hits = 0;

    // per lane (capacity: a tile)
    std::vector<PathState> m_state;
    std::vector<PixelSampler> m_sampler;
    std::vector<uint32_t> m_pixel;  ///< index into the tile (row-major)
    std::vector<Ray> m_rays;
    std::vector<Hit> m_hits;
    std::vector<uint8_t> m_occluded;
    std::vector<uint32_t> m_skip_light;  ///< per lane: the light proxy its shadow ray skips
    std::vector<uint32_t> m_live, m_shadowed, m_scattering, m_pending, m_ended;
    // random numbers computed ahead for every live lane (prefetch_dimensions)
    std::vector<uint32_t> m_c0, m_c1, m_c2, m_w0, m_w1;
    std::vector<uint32_t> m_words;  ///< per lane: k_prefetch dimensions x 2 words
    std::vector<uint32_t> m_prefix;  ///< per lane, with Sobol points: sobol::seed_prefix of its sample
    // the diffuse lanes of a round: their batch lanes, the lights their shadow rays aim at
    bool m_use_lanes = true;
    std::unique_ptr<DiffuseLanes> m_lanes;
    std::vector<uint32_t> m_diffuse, m_diffuse_light;
    // the rect lights whose samples the lanes compute (Light::rect_constants): per light
    // its slot or DiffuseLanes::k_no_rect_slot, per slot the constants
    std::vector<uint8_t> m_rect_slot;
    std::vector<RectLightConstants> m_rect;
    // the same for the sphere lights (Light::sphere_constants)
    std::vector<uint8_t> m_sphere_slot;
    std::vector<SphereLightConstants> m_sphere;
    // the lanes of a round placed from the top down and shaded one at a time: batch
    // lanes, materials, constant preview BSDFs (null: make_bsdf_at), texture coordinates
    std::vector<uint32_t> m_placed, m_placed_material;
    std::vector<const PreviewSurfaceBsdf*> m_placed_preview;
    std::vector<Vec2> m_placed_uv;
    // the preview lanes of a round (diffuse_lanes.h): their batch lanes and lights
    std::unique_ptr<DiffuseLanes> m_preview_lanes;
    std::vector<uint32_t> m_preview, m_preview_light;
    // per material: a constant preview BSDF of the preview lanes' model, and its constants
    std::vector<uint8_t> m_lane_model;
    std::vector<PreviewSurfaceBsdf::LaneConstants> m_lane_constants;

    /// Stage 1 of diffuse_lanes.h for lane l: false if its hit is not one the lanes take
    /// (a static instance's triangle with a constant Lambertian, a constant preview BSDF
    /// or a Scene::lane_material on a mesh without primvars).
    bool gather_diffuse(uint32_t l, PathCounters& counters);
    /// Lane k of L takes batch lane l's throughput, depth and the bounce's numbers.
    void set_path(DiffuseLanes& L, size_t k, uint32_t l) const;
    /// Preview lane k of L takes the model's constants and the material's partition flag.
    void set_model(DiffuseLanes& L, size_t k, const PreviewSurfaceBsdf::LaneConstants& pc, uint32_t material_id) const;
    /// Stages 2-6 of diffuse_lanes.h for the lanes in m_diffuse; stage 2 for those in
    /// m_placed, then the preview lanes' stages for those whose BSDF is the preview lanes'
    /// model and PathTracer::step(BsdfHit) for the others.
    void shade_diffuse_lanes(PathCounters& counters);
    /// Stage 3 of diffuse_lanes.h for the lanes [0, lanes.size()) of L (batch lanes
    /// `lanes`): where wants(k, state), the light sample of next-event estimation; the
    /// light's index into light[k].
    template <class Wants>
    void light_samples(DiffuseLanes& L, const std::vector<uint32_t>& lanes, std::vector<uint32_t>& light,
                       Wants&& wants);
    /// Stage 6: the lanes' results back into their paths (`preview`: L holds preview lanes).
    void scatter_lanes(const DiffuseLanes& L, const std::vector<uint32_t>& lanes, const std::vector<uint32_t>& light,
                       bool preview, PathCounters& counters);

    /// Hands every lane of `lanes` the numbers of dimensions [first(lane), first(lane) +
    /// count) (PixelSampler::prefetch), computed for all of them at once.
    template <class First>
    void prefetch_dimensions(const std::vector<uint32_t>& lanes, uint32_t count, First&& first);
};

}  // namespace cmlt
