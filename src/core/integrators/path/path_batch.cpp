// Path tracing in batches; see path_batch.h.
#include "integrators/path/path_batch.h"

#include "accel/accel.h"
#include "cameras/camera.h"
#include "film/filter.h"
#include "film/pass_splatter.h"
#include "integrators/path/path_tracer_impl.h"
#include "scene/scene.h"

namespace cmlt {

namespace {
/// Dimensions a lane prefetches per round: one bounce's (PathTracer::k_dims_per_bounce).
constexpr uint32_t k_prefetch = PathTracer::k_dims_per_bounce;
}  // namespace

template <class First>
void PathBatch::prefetch_dimensions(const std::vector<uint32_t>& lanes, uint32_t count, First&& first) {
    // Philox of every lane's dimensions at once: the numbers themselves, or with a Sobol
    // sequence the dimensions' seeds (counter (pixel, sequence_seed_sample, d)), from
    // which each lane's point follows (sampling/rng.h pixel_words)
    if (lanes.empty()) return;
    const PixelSequence seq = m_tracer.sequence();
    const bool sobol = low_discrepancy(seq);
    // a batch's lanes are samples of one index (trace_tile's s): one counter word for all
    const uint32_t sample = m_sampler[lanes[0]].sample();
    const uint32_t c1 = sobol ? sequence_seed_sample(seq, sample) : sample;
    size_t n = 0;
    for (uint32_t l : lanes) {
        const uint32_t d0 = first(l);
        for (uint32_t k = 0; k < count; ++k, ++n) {
            m_c0[n] = m_sampler[l].pixel();
            m_c1[n] = c1;
            m_c2[n] = d0 + k;
        }
    }
    philox4x32_lanes(n, m_c0.data(), m_c1.data(), m_c2.data(), uint32_t(RngStream::camera_path),
                     seed_key(m_seed), m_w0.data(), m_w1.data());
    if (sobol) sobol::scrambled_points_lanes(n, sequence_index(seq, sample), m_w0.data(), m_w1.data());
    n = 0;
    for (uint32_t l : lanes) {
        uint32_t* w = &m_words[size_t(l) * 2 * k_prefetch];
        for (uint32_t k = 0; k < count; ++k, ++n) {
            w[2 * k] = m_w0[n];
            w[2 * k + 1] = m_w1[n];
        }
        m_sampler[l].prefetch(first(l), count, w);
    }
}

PathBatch::PathBatch(const PathTracer& tracer, const Scene& scene, const Camera& camera, const PixelFilter& filter,
                     bool motion_blur, uint64_t seed, int width, int height, int reach, int packet_width,
                     KeyShift shift)
    : m_tracer(tracer), m_scene(scene), m_camera(camera), m_filter(filter), m_motion_blur(motion_blur),
      m_seed(seed), m_width(width), m_height(height), m_reach(reach), m_shift(shift),
      m_packet_width(packet_width) {
    const size_t n = size_t(k_tile_size) * size_t(k_tile_size);
    m_state.resize(n);
    m_sampler.assign(n, PixelSampler(0, 0, 0));
    m_pixel.resize(n);
    m_rays.resize(n);
    m_hits.resize(n);
    m_occluded.resize(n);
    m_live.reserve(n);
    m_shadowed.reserve(n);
    m_scattering.reserve(n);
    for (auto* v : {&m_c0, &m_c1, &m_c2, &m_w0, &m_w1}) v->resize(n * k_prefetch);
    m_words.resize(n * 2 * k_prefetch);
}

void PathBatch::trace_tile(const Tile& tile, uint32_t s, PathCounters& c, Spectrum* L, float* w, Vec2* p) {
    const int tw = tile.x1 - tile.x0, th = tile.y1 - tile.y0;
    // Lanes: the tile's pixels in 4x4 blocks (camera rays of a packet are neighbours).
    m_live.clear();
    uint32_t lane = 0;
    for (int by = 0; by < th; by += 4)
        for (int bx = 0; bx < tw; bx += 4)
            for (int y = by; y < std::min(by + 4, th); ++y)
                for (int x = bx; x < std::min(bx + 4, tw); ++x) {
                    const uint32_t pixel =
                        PassSplatter::window_key(tile.x0 + x, tile.y0 + y, m_width, m_height, m_reach, m_shift);
                    m_pixel[lane] = uint32_t(y * tw + x);
                    m_sampler[lane] = PixelSampler(m_seed, pixel, s, RngStream::camera_path, m_tracer.sequence());
                    m_live.push_back(lane);
                    ++lane;
                }
    // Camera rays (film position: dimension 0).
    prefetch_dimensions(m_live, 1, [](uint32_t) { return 0u; });
    for (uint32_t l : m_live) {
        const uint32_t i = m_pixel[l];
        const int px = tile.x0 + int(i) % tw, py = tile.y0 + int(i) / tw;
        float& weight = w[i];
        weight = 1.f;
        const Ray ray = m_tracer.camera_ray(m_camera, m_filter, m_motion_blur, m_sampler[l], m_seed, px, py,
                                            m_sampler[l].pixel(), s, &weight, p ? &p[i] : nullptr);
        m_tracer.begin(m_state[l], ray, c);
    }

    const Accel& accel = m_scene.accel();
    while (!m_live.empty()) {
        // Closest hits of every live path.
        for (uint32_t l : m_live) m_rays[l] = m_state[l].ray;
        m_packets += accel.intersect_lanes(m_rays.data(), m_live.data(), m_live.size(), m_hits.data(),
                                           m_packet_width);
        // Shade: emission, the next ray, a pending shadow ray. A lane that scatters reads
        // the dimensions of its bounce (PathTracer::scatter): computed here, for every
        // lane that hit a mesh, at once (a miss or an analytic light ends the path).
        m_scattering.clear();
        for (uint32_t l : m_live)
            if (m_hits[l].valid()) m_scattering.push_back(l);
        prefetch_dimensions(m_scattering, k_prefetch,
                            [&](uint32_t l) { return 1 + m_state[l].bounce * PathTracer::k_dims_per_bounce; });
        m_shadowed.clear();
        const bool lights = m_scene.has_analytic_area_lights();
        for (uint32_t l : m_live) {
            PathState& st = m_state[l];
            const Hit& h = m_hits[l];
            // The diffuse fast path: a mesh hit (no analytic light in front of it) on a
            // constant Lambertian; everything else through the full hit.
            uint32_t light;
            Spectrum le;
            if (h.valid() && !(lights && m_scene.nearest_light(m_rays[l], h.t, &light, &le) < k_infinity)) {
                HitGeometry g;
                m_scene.hit_geometry(m_rays[l], h, &g);
                if (const Spectrum* r = m_scene.constant_lambert(g.material_id)) {
                    m_tracer.step(st, LambertHit{&g, r}, m_sampler[l], c);
                } else {
                    m_tracer.step(st, m_scene.resolve_hit(m_rays[l], h), m_sampler[l], c);
                }
            } else {
                m_tracer.step(st, m_scene.resolve_hit(m_rays[l], h), m_sampler[l], c);
            }
            if (!st.has_shadow) continue;
            // Scene::transmittance, split around the BVH query: analytic lights first.
            if (m_scene.blocked_by_light(st.shadow, st.shadow_light)) {
                PathTracer::finish_shadow(st, 0.f, 1.f);
                continue;
            }
            m_rays[l] = st.shadow;
            m_shadowed.push_back(l);
        }
        // Visibility of the shadow rays.
        m_packets += accel.occluded_lanes(m_rays.data(), m_shadowed.data(), m_shadowed.size(),
                                          m_occluded.data(), m_packet_width);
        for (uint32_t l : m_shadowed) {
            float pass_pdf = 1.f;
            const float tr = m_scene.transmittance_given(m_rays[l], m_occluded[l] != 0, &pass_pdf);
            PathTracer::finish_shadow(m_state[l], tr, pass_pdf);
        }
        // Live lanes keep their order.
        size_t k = 0;
        for (uint32_t l : m_live)
            if (!m_state[l].done) m_live[k++] = l;
        m_live.resize(k);
    }
    for (uint32_t l = 0; l < lane; ++l) L[m_pixel[l]] = m_state[l].L;
}

}  // namespace cmlt
