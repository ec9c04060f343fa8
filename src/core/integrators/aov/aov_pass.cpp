#include "integrators/aov/aov_pass.h"

#include "cameras/camera.h"
#include "film/filter.h"
#include "film/pass_splatter.h"
#include "materials/material_eval.h"
#include "math/safe_math.h"
#include "sampling/rng.h"
#include "util/error.h"
#include "util/fp_mode.h"

#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>

namespace cmlt {

namespace {

constexpr int k_aov_tile = 16;

}  // namespace

AovResult render_aovs(Scene& scene, const RenderSettings& settings, int samples) {
    if (settings.width < 1 || settings.height < 1)
        CMLT_THROW(SettingsError, "RenderSettings.width and height must be >= 1, got "
                                      << settings.width << " x " << settings.height);
    if (int64_t(settings.width) * int64_t(settings.height) > (int64_t(1) << 31))
        CMLT_THROW(SettingsError, "RenderSettings.width * height is too large");
    if (settings.threads < 0)
        CMLT_THROW(SettingsError, "RenderSettings.threads must be >= 0, got " << settings.threads);
    if (samples < 1 || samples > 4096)
        CMLT_THROW(SettingsError, "render_aovs: samples must be 1..4096, got " << samples);
    if (!scene.has_camera())
        throw SceneError("render_aovs: the scene has no camera (call set_camera)");
    if (scene.dirty()) scene.commit();

    const int W = settings.width, H = settings.height;
    Camera camera(scene.camera_desc(), W, H);
    const PixelFilter filter = PixelFilter::from_settings(settings.pixel_filter, settings.filter_radius);
    const Mat4& cam_m = scene.camera_desc().transform;
    const Vec3 cam_pos = cam_m.transform_point(Vec3(0.f));
    const Vec3 axis = normalize(cam_m.transform_vector(Vec3(0.f, 0.f, -1.f)));

    AovResult res;
    res.width = W;
    res.height = H;
    res.albedo.assign(size_t(W) * H * 3, 0.f);
    res.normal.assign(size_t(W) * H * 3, 0.f);
    res.depth.assign(size_t(W) * H, 0.f);

    struct Tile {
        int x0, y0, x1, y1;
    };
    std::vector<Tile> tiles;
    for (int y = 0; y < H; y += k_aov_tile)
        for (int x = 0; x < W; x += k_aov_tile)
            tiles.push_back({x, y, std::min(x + k_aov_tile, W), std::min(y + k_aov_tile, H)});

    const int threads = settings.threads > 0 ? settings.threads : tbb::info::default_concurrency();
    tbb::task_arena arena(threads);
    std::atomic<uint64_t> rays{0};
    // the beauty's keys: they follow the frame's film offset (film/pass_splatter.h)
    const KeyShift shift = KeyShift::of(settings);
    auto t0 = std::chrono::steady_clock::now();
    arena.execute([&] {
        tbb::parallel_for(
            tbb::blocked_range<size_t>(0, tiles.size(), 1),
            [&](const tbb::blocked_range<size_t>& r) {
                ScopedFtzDaz ftz;
                uint64_t n_rays = 0;
                for (size_t ti = r.begin(); ti != r.end(); ++ti) {
                    const Tile& tile = tiles[ti];
                    for (int y = tile.y0; y < tile.y1; ++y)
                        for (int x = tile.x0; x < tile.x1; ++x) {
                            const uint32_t pixel = PassSplatter::window_key(x, y, W, H, 0, shift);
                            Spectrum albedo(0.f);
                            Vec3 nsum(0.f), nfirst(0.f);
                            float zmin = k_infinity;
                            int hits = 0;
                            float wsum = 0.f;  // the filter weights' sum (the film's divisor)
                            for (int s = 0; s < samples; ++s) {
                                // The beauty render's film position of sample s (the pixel
                                // filter's offset and weight, as pt's)
                                PixelSampler sampler(settings.seed, pixel, uint32_t(s), RngStream::camera_path,
                                                     pixel_sequence(settings));
                                float w = 1.f;
                                const Vec2 p_film = filter.film_position(x, y, sampler.get2d(), &w);
                                wsum += w;
                                Ray ray = camera.generate_ray(p_film);
                                SceneHit hit = scene.intersect(ray);
                                ++n_rays;
                                if (hit.kind == SceneHit::Kind::miss || !std::isfinite(hit.t))
                                    continue;
                                Vec3 n;
                                Vec3 p;
                                if (hit.kind == SceneHit::Kind::surface) {
                                    // The integrators' textured material at the hit (make_bsdf):
                                    // the diffuse texture at st, the normal map's shading normal.
                                    const SurfaceInteraction& si = hit.si;
                                    const Material& mat = scene.material(si.material_id);
                                    const Bsdf bsdf = make_bsdf(mat, si, scene.textures());
                                    albedo += diffuse_colour(mat, si.uv, scene.textures(), si.primvars, si.n_primvars) * w;
                                    n = face_forward(bsdf.shading_normal(), si.wo);
                                    p = si.p;
                                } else {
                                    albedo += Spectrum(clamp01(hit.le.x), clamp01(hit.le.y),
                                                       clamp01(hit.le.z)) * w;
                                    n = -ray.d;
                                    p = ray.o + ray.d * hit.t;
                                }
                                // both projections: distance along the viewing axis
                                float z = dot(p - cam_pos, axis);
                                if (!std::isfinite(z)) continue;
                                if (hits == 0) nfirst = n;
                                nsum += n * w;
                                zmin = std::min(zmin, std::max(z, 0.f));
                                ++hits;
                            }
                            const size_t i3 = size_t(pixel) * 3;
                            const float inv = wsum != 0.f ? 1.f / wsum : 0.f;
                            res.albedo[i3 + 0] = albedo.x * inv;
                            res.albedo[i3 + 1] = albedo.y * inv;
                            res.albedo[i3 + 2] = albedo.z * inv;
                            if (hits > 0) {
                                float len = length(nsum);
                                Vec3 n = len > 1e-6f ? nsum / len : normalize(nfirst);
                                res.normal[i3 + 0] = n.x;
                                res.normal[i3 + 1] = n.y;
                                res.normal[i3 + 2] = n.z;
                                res.depth[pixel] = zmin;
                            }
                        }
                }
                rays.fetch_add(n_rays, std::memory_order_relaxed);
            },
            tbb::simple_partitioner());
    });
    res.rays = rays.load();
    res.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return res;
}

}  // namespace cmlt
