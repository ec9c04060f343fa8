// BDPT's (1, 1) strategy for path-traced passes; see lens_light_tracing.h.
#include "integrators/path/lens_light_tracing.h"

#include "film/filter.h"
#include "integrators/path/caustic_light_tracing.h"
#include "lights/light.h"
#include "math/frame.h"
#include "sampling/rng.h"
#include "sampling/rng_domains.h"
#include "scene/interaction.h"
#include "scene/scene.h"

#include <algorithm>
#include <cmath>

namespace cmlt {

std::vector<uint32_t> LensLightTracing::sub_pixel_lights(const Scene& scene, const Camera& camera, int width,
                                                        int height, float margin) {
    std::vector<uint32_t> out;
    const CameraImportance importance(camera, width, height, margin);
    if (!importance.connectable()) return out;
    const Vec3 eye = importance.sample_lens(Vec2(0.5f, 0.5f));
    for (size_t i = 0; i < scene.light_count(); ++i) {
        const Light& l = scene.light(i);
        Vec3 c;
        float r = 0.f;
        Spectrum le;
        if (l.is_delta() || l.is_infinite() || !l.bounding_sphere(&c, &r) || !l.le_toward(c, Vec3(0.f, 0.f, 1.f), &le))
            continue;
        const Vec3 d = c - eye;
        const float dist = length(d);
        if (!(dist > r) || !std::isfinite(dist)) continue;
        // its size on the film: the centre's raster position and a point r off it,
        // across the line of sight
        const Vec3 q = c + Frame(d / dist).s * r;
        Vec2 pc, pq;
        if (!camera.lens_ray_to_raster(eye, d / dist, &pc) || !camera.lens_ray_to_raster(eye, normalize(q - eye), &pq))
            continue;
        if (pc.x < -margin || pc.y < -margin || pc.x > float(width) + margin || pc.y > float(height) + margin)
            continue;
        const float dx = pq.x - pc.x, dy = pq.y - pc.y;
        if (!(2.f * std::sqrt(dx * dx + dy * dy) < k_max_pixels)) continue;
        out.push_back(uint32_t(i));
    }
    return out;
}

LensLightTracing::LensLightTracing(const Scene& scene, const Camera& camera, int width, int height,
                                   float margin)
    : m_scene(scene), m_importance(camera, width, height, margin),
      m_lights(sub_pixel_lights(scene, camera, width, height, margin)), m_slot(scene.light_count(), -1) {
    std::vector<double> power;
    for (size_t k = 0; k < m_lights.size(); ++k) {
        m_slot[m_lights[k]] = int32_t(k);
        power.push_back(std::max(double(scene.light(m_lights[k]).power()), 0.0));
    }
    if (!m_lights.empty()) m_dist = DiscreteDistribution(power);
}

void LensLightTracing::densities(const Vec3& p_lens, const Vec3& p, uint32_t slot, float* p_cam,
                                 float* p_light) const {
    *p_cam = *p_light = 0.f;
    const Light& l = m_scene.light(m_lights[slot]);
    Vec3 w = p - p_lens;
    const float d2 = length_squared(w);
    if (!(d2 > 0.f)) return;
    w = w / std::sqrt(d2);
    const Vec3 n = l.emitter_normal(p);
    *p_cam = m_importance.pdf_dir(p_lens, w) * std::fabs(dot(n, w)) / d2;
    float pdf_pos = 0.f, pdf_dir = 0.f;
    l.pdf_le(p, -w, &pdf_pos, &pdf_dir);
    *p_light = m_dist.pmf(slot) * pdf_pos;
}

float LensLightTracing::camera_share(const Vec3& p_lens, const Vec3& p, uint32_t slot) const {
    float pc, pl;
    densities(p_lens, p, slot, &pc, &pl);
    const double c2 = double(pc) * double(pc), l2 = double(pl) * double(pl);
    const double w = c2 + l2 > 0.0 ? c2 / (c2 + l2) : 1.0;
    return std::isfinite(w) ? float(w) : 1.f;
}

float LensLightTracing::camera_hit_weight(const Vec3& p_lens, const Vec3& p, uint32_t light_index) const {
    const int32_t slot = light_index < m_slot.size() ? m_slot[light_index] : -1;
    if (slot < 0) return 1.f;
    return camera_share(p_lens, p, uint32_t(slot));
}

bool LensLightTracing::sample(uint64_t seed, uint32_t pixel, uint32_t index, bool motion_blur,
                              Vec2* p_raster, Spectrum* value, uint64_t* shadow_rays) const {
    if (m_lights.empty()) return false;
    const Philox4x32Key key = seed_key(seed);
    const Philox4x32Counter a = philox4x32(pixel_counter(pixel, index, 0, RngStream::lens_light), key);
    const Philox4x32Counter b = philox4x32(pixel_counter(pixel, index, 1, RngStream::lens_light), key);
    float pmf = 0.f;
    const size_t slot = m_dist.sample(uint_to_unit_float(a[0]), &pmf);
    const Light& l = m_scene.light(m_lights[slot]);
    // the point (sample_le's direction is not used: the lens gives it)
    const LightLeSample les = l.sample_le(Vec2(uint_to_unit_float(a[1]), uint_to_unit_float(a[2])),
                                          Vec2(0.5f, 0.5f));
    if (!(les.pdf_pos > 0.f) || !(pmf > 0.f)) return false;
    const Vec3 p_lens = m_importance.sample_lens(m_importance.has_lens()
                                                     ? Vec2(uint_to_unit_float(b[0]), uint_to_unit_float(b[1]))
                                                     : Vec2(0.f, 0.f));
    Vec3 w = p_lens - les.p;  // toward the lens
    const float d2 = length_squared(w);
    if (!(d2 > 0.f)) return false;
    w = w / std::sqrt(d2);
    Spectrum le;
    l.le_toward(les.p, w, &le);
    if (is_black(le)) return false;
    Vec2 pr;
    const float we = m_importance.we(p_lens, -w, &pr);
    if (!(we > 0.f)) return false;
    const float cos_cam = m_importance.cos_axis(-w);
    const float cos_l = std::fabs(dot(les.n, w));
    const float mis = 1.f - camera_share(p_lens, les.p, uint32_t(slot));
    const Spectrum v = le * (cos_l * we * cos_cam * mis / (pmf * les.pdf_pos * d2 * m_importance.pdf_lens()));
    if (is_black(v) || !is_finite(v)) return false;
    // visibility: the segment lens - light point (analytic lights are not in the BVH and
    // do not block it); pass-through surfaces on the way are crossed with their weight
    Ray ray(p_lens, les.p - p_lens, 0.f, 1.f - k_shadow_epsilon);
    ray.time = motion_blur ? uint_to_unit_float(a[3]) : 0.f;
    *shadow_rays += 1;
    float pass_pdf = 1.f;
    const float tr = m_scene.transmittance(ray, &pass_pdf);
    if (!(tr > 0.f)) return false;
    *value = v * tr;
    *p_raster = pr;
    return true;
}

LensPass::LensPass(const LensLightTracing& lens, const PixelFilter& filter, int width, int height,
                   const CausticLightTracing* caustic)
    : m_lens(lens), m_caustic(caustic && caustic->active() ? caustic : nullptr), m_filter(filter), m_width(width), m_height(height),
      m_scale(filter.window_area(width, height) / (double(width) * double(height))), m_rows(size_t(height)),
      m_image(size_t(width) * size_t(height) * 3) {}

const double* LensPass::trace(tbb::task_arena& arena, FrameCounters& counters, uint64_t seed, uint32_t sample,
                              bool motion_blur) {
    parallel_tasks(arena, counters, size_t(m_height), size_t(2), [&](const tbb::blocked_range<size_t>& r) {
        PathCounters c;
        for (size_t y = r.begin(); y != r.end(); ++y) {
            auto& out = m_rows[y];
            out.clear();
            for (int x = 0; x < m_width; ++x) {
                const uint32_t pixel = uint32_t(y) * uint32_t(m_width) + uint32_t(x);
                Vec2 pr;
                Spectrum v;
                const uint64_t shadow0 = c.shadow_rays;
                if (m_lens.sample(seed, pixel, sample, motion_blur, &pr, &v, &c.shadow_rays)) out.emplace_back(pr, v);
                c.rays += c.shadow_rays - shadow0;
                if (m_caustic) m_caustic->trace(seed, pixel, sample, motion_blur, out, &c.rays, &c.shadow_rays);
            }
        }
        counters.add(c);
    });
    std::fill(m_image.begin(), m_image.end(), 0.0);
    for (const auto& row : m_rows)
        for (const auto& sp : row) m_filter.splat(sp.first, sp.second, m_scale, m_width, m_height, m_image.data());
    return m_image.data();
}

}  // namespace cmlt
