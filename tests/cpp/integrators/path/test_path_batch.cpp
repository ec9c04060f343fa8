// The batched path tracer (integrators/path/path_batch.h, its constant-Lambertian hits in
// the structure-of-arrays lanes of diffuse_lanes.h) against the scalar reference:
// PathTracer::pixel_sample, one path and one query at a time (path_tracer.h). Without
// packets the batch answers every query as the reference does and must give its image
// bit for bit; with packets (Embree's packet kernels may differ from single rays in the
// last ulp of a hit) the two images must agree within their confidence intervals.
#include "test_scenes.h"
#include "test_util.h"

#include "cameras/camera.h"
#include "film/film.h"
#include "film/filter.h"
#include "film/pass_splatter.h"
#include "integrators/common/frame_loop.h"
#include "integrators/common/render.h"
#include "integrators/path/caustic_light_tracing.h"
#include "integrators/path/lens_light_tracing.h"
#include "integrators/path/path_tracer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <memory>
#include <string>

#include <tbb/task_arena.h>

using namespace cmlt;
using namespace cmlt::test;

namespace {

/// A 4x4 RGB checker texture; its id.
int32_t add_checker(Scene& s) {
    auto texels = std::make_shared<std::vector<float>>();
    for (int i = 0; i < 16; ++i) {
        const float a = ((i + i / 4) % 2) ? 0.85f : 0.2f;
        texels->insert(texels->end(), {a, 0.5f * a + 0.1f, 1.f - a});
    }
    TextureDesc d;
    d.data = texels->data();
    d.width = d.height = 4;
    d.channels = 3;
    d.owner = texels;
    return int32_t(s.add_texture(d, "checker"));
}

/// box_scene's four materials (walls, red, green, the quad emitting `le`).
std::vector<Material> box_materials(float le) {
    return {Material{Spectrum(0.7f), Spectrum(0.f)}, Material{Spectrum(0.7f, 0.15f, 0.1f), Spectrum(0.f)},
            Material{Spectrum(0.1f, 0.6f, 0.15f), Spectrum(0.f)}, Material{Spectrum(0.5f), Spectrum(le)}};
}

/// A rect light under the ceiling, with `side` a second one on a wall, and a small sphere light.
void add_analytic_lights(Scene& s, bool side) {
    LightDesc rect;
    rect.kind = LightDesc::Kind::rect;
    rect.transform = Mat4::translate(0, 0.95, 0) * Mat4::rotate(-90, 1, 0, 0);
    rect.width = rect.height = 0.5f;
    rect.radiance = Spectrum(8.f);
    s.add_light(rect);
    if (side) {
        LightDesc wall = rect;
        wall.transform = Mat4::translate(0.9, 0.2, 0) * Mat4::rotate(-90, 0, 1, 0);
        wall.width = 0.3f;
        wall.radiance = Spectrum(2.f, 3.f, 4.f);
        s.add_light(wall);
    }
    s.add_light(sphere_light(Vec3(-0.5f, 0.3f, -0.4f), 0.08f, Spectrum(20.f, 15.f, 10.f)));
}

RenderSettings settings(int spp, bool packets) {
    RenderSettings st;
    st.width = 40;
    st.height = 30;
    st.spp = spp;
    st.threads = 2;
    st.seed = 7;
    st.integrator = "pt";
    st.packets = packets;
    return st;
}

/// The image of the scalar reference: every pixel's samples through pixel_sample, added
/// to a film in sample order as the integrator does; for a wide filter or with caustic
/// light tracing (a scene with glass), pass by pass, every source pixel of the window
/// sampled uniformly and splatted (film/pass_splatter.h) with the pass's light paths.
std::vector<float> reference_image(const Scene& scene, const RenderSettings& st, std::vector<float>* variance) {
    const Camera camera(scene.camera_desc(), st.width, st.height);
    const PixelFilter filter = PixelFilter::from_settings(st.pixel_filter, st.filter_radius);
    PathTracer tracer(scene, st.max_depth);
    tracer.set_sequence(pixel_sequence(st));
    const LensLightTracing lens(scene, camera, st.width, st.height, filter.margin());
    const CausticLightTracing caustic(scene, camera, st.width, st.height, filter.margin(), st.max_depth);
    const bool caustic_on = st.caustic_tracing && caustic.active();
    if (caustic_on) tracer.set_caustic_light_tracing(&caustic);
    Film film(st.width, st.height);
    film.set_variance_block(variance_block(pixel_sequence(st)));
    PathCounters c;
    PassSplatter splatter(filter, film);
    if (!splatter.active() && !caustic_on) {
        for (int y = 0; y < st.height; ++y)
            for (int x = 0; x < st.width; ++x)
                for (int s = 0; s < st.spp; ++s) {
                    float w = 1.f;
                    const Spectrum L = tracer.pixel_sample(camera, filter, scene.motion_blur(), st.seed, x, y,
                                                           uint32_t(y * st.width + x), uint32_t(s), c, &w);
                    film.add_sample(x, y, uint32_t(s), L, w);
                }
    } else {
        const PixelFilter unit_box;
        const int R = splatter.reach();
        tbb::task_arena arena(1);
        LensPass light_pass(lens, filter, st.width, st.height, caustic_on ? &caustic : nullptr);
        FrameCounters counters;
        for (int s = 0; s < st.spp; ++s) {
            for (int y = -R; y < st.height + R; ++y)
                for (int x = -R; x < st.width + R; ++x) {
                    float w = 1.f;
                    Vec2 p;
                    const Spectrum L = tracer.pixel_sample(camera, unit_box, scene.motion_blur(), st.seed, x, y,
                                                           splatter.key(x, y), uint32_t(s), c, &w, &p);
                    splatter.set(x, y, p, L, uint32_t(s));
                }
            const double* splats =
                caustic_on ? light_pass.trace(arena, counters, st.seed, uint32_t(s), scene.motion_blur()) : nullptr;
            splatter.gather(arena, uint32_t(s), splats);
        }
    }
    std::vector<float> image(size_t(3) * st.width * st.height);
    variance->resize(image.size());
    film.develop(image.data(), variance->data());
    return image;
}

void check_scene(const std::function<void(Scene&)>& build, const char* what, bool caustic_tracing = true) {
    Scene scene;
    build(scene);
    scene.select_kernels(false);
    for (const char* filter : {"box", "gaussian"})
      for (const char* sampler : {"sobol", "independent", "sobol-blocks"}) {
        const std::string name = std::string(what) + " (" + filter + ", " + sampler + ")";
        // 1. no packets: the reference's image bit for bit (sobol-blocks: 3 blocks, so
        // that the variance, which comes from the blocks, is not 0)
        RenderSettings st = settings(std::string(sampler) == "sobol-blocks" ? 3 * int(k_sobol_block) : 8, false);
        st.pixel_filter = filter;
        st.sampler = sampler;
        st.caustic_tracing = caustic_tracing;
        std::vector<float> ref_var;
        const std::vector<float> ref = reference_image(scene, st, &ref_var);
        const RenderResult scalar = render(scene, st);
        ASSERT_EQ(scalar.image.size(), ref.size());
        EXPECT_EQ(std::memcmp(scalar.image.data(), ref.data(), ref.size() * sizeof(float)), 0) << name;
        EXPECT_EQ(std::memcmp(scalar.variance.data(), ref_var.data(), ref.size() * sizeof(float)), 0) << name;
        // the Lambertian walls' hits went through the diffuse lanes (diffuse_lanes.h), so
        // the comparison above holds them to the per-lane routine's floats
        EXPECT_GT(scalar.stats.lane_hits, 0u) << name;
        EXPECT_LE(scalar.stats.lane_hits, scalar.stats.rays - scalar.stats.shadow_rays) << name;
        // 2. packets: the same estimator; image means per channel within 4.5 standard
        // errors of the difference (two independent-looking renders: different last-ulp
        // hits decorrelate them only where a hit changes, so this is conservative; the
        // splatted pixels' correlation in the standard error: image_stats.h)
        st.packets = true;
        const RenderResult packets = render(scene, st);
        EXPECT_GT(packets.stats.packets, 0u) << name;
        const double corr = packets.stats.pixel_correlation;
        for (int c = 0; c < 3; ++c) {
            double a = 0, b = 0, va = 0, vb = 0;
            const size_t n = size_t(st.width) * st.height;
            for (size_t i = 0; i < n; ++i) {
                a += ref[3 * i + c];
                b += packets.image[3 * i + c];
                va += ref_var[3 * i + c];
                vb += packets.variance[3 * i + c];
            }
            const double se = std::sqrt(corr * (va + vb)) / double(n);
            EXPECT_LT(std::fabs(a - b) / double(n), 4.5 * se + 1e-6) << name << " channel " << c;
        }
        EXPECT_EQ(packets.stats.nan_samples, 0u) << name;
    }
}

}  // namespace

TEST(PathBatch, MatchesTheScalarReferenceOnTheBox) {
    check_scene([](Scene& s) { box_scene(s, 10.f, true); s.commit(); }, "box");
}

TEST(PathBatch, MatchesTheScalarReferenceOnPreviewSurfaces) {
    // glossy UsdPreviewSurfaces with constant inputs (Scene::constant_preview): placed in
    // the lanes, shaded by PathTracer::step(PreviewHit); a mirror-like clear coat on one
    check_scene(
        [](Scene& s) {
            box_scene(s, 10.f, true);
            std::vector<Material> m = box_materials(10.f);
            for (int i = 0; i < 3; ++i) {
                m[size_t(i)].preview = true;
                m[size_t(i)].roughness = 0.25f + 0.25f * float(i);
            }
            m[1].metallic = 0.6f;
            m[2].clearcoat = 0.8f;
            s.set_materials(m);
            s.commit();
            for (uint32_t i = 0; i < 3; ++i) EXPECT_NE(s.constant_preview(i), nullptr) << i;
            EXPECT_EQ(s.constant_preview(3), nullptr);  // emissive
        },
        "preview box");
}

TEST(PathBatch, MatchesTheScalarReferenceOnTexturedMaterials) {
    // textured Lambert, textured preview surface (colour and roughness) and a textured
    // preview the diffuse-only kernel renders (Scene::lane_material): placed in the
    // lanes, their BSDF made from the hit's uv (make_bsdf_at)
    check_scene(
        [](Scene& s) {
            box_scene(s, 10.f, true);
            const int32_t tex = add_checker(s);
            std::vector<Material> m = box_materials(10.f);
            m[0].tex_diffuse = tex;
            m[1].preview = true;
            m[1].tex_diffuse = tex;
            m[1].tex_roughness = tex;
            m[1].ch_roughness = 1;
            m[2].preview = true;
            m[2].ior = 1.f;  // no specular lobe: the diffuse-only kernel
            m[2].tex_diffuse = tex;
            s.set_materials(m);
            s.commit();
            for (uint32_t i = 0; i < 3; ++i) EXPECT_NE(s.lane_material(i), nullptr) << i;
            EXPECT_EQ(s.lane_material(3), nullptr);  // emissive
        },
        "textured box");
}

TEST(PathBatch, MatchesTheScalarReferenceWithAnalyticLights) {
    check_scene(
        [](Scene& s) {
            box_scene(s, 0.f, false);
            add_analytic_lights(s, false);
            s.commit();
        },
        "analytic lights");
}

TEST(PathBatch, MatchesTheScalarReferenceOnPreviewSurfacesUnderAnalyticLights) {
    // placed lanes (constant preview BSDFs, a textured preview surface) lit by two rect
    // lights whose samples the diffuse lanes take in lanes (Light::rect_constants) and a
    // sphere light (the per-lane routine samples every light for the placed lanes)
    check_scene(
        [](Scene& s) {
            box_scene(s, 0.f, false);
            const int32_t tex = add_checker(s);
            std::vector<Material> m = box_materials(0.f);
            for (int i = 0; i < 4; ++i) {
                m[size_t(i)].preview = true;
                m[size_t(i)].roughness = 0.2f + 0.2f * float(i);
            }
            m[1].metallic = 0.6f;
            m[2].clearcoat = 0.8f;
            m[3].tex_diffuse = tex;
            s.set_materials(m);
            add_analytic_lights(s, true);
            s.commit();
            for (uint32_t i = 0; i < 3; ++i) EXPECT_NE(s.constant_preview(i), nullptr) << i;
            EXPECT_NE(s.lane_material(3), nullptr);
            RectLightConstants c;
            EXPECT_TRUE(s.light(0).rect_constants(&c));
            EXPECT_TRUE(s.light(1).rect_constants(&c));
            EXPECT_FALSE(s.light(2).rect_constants(&c));
        },
        "preview box, analytic lights");
}

TEST(PathBatch, MatchesTheScalarReferenceThroughPassThroughSurfaces) {
    check_scene([](Scene& s) { pass_through_box(s); }, "pass-through box");
}

TEST(PathBatch, MatchesTheScalarReferenceThroughGlass) {
    check_scene([](Scene& s) { glass_scene(s); }, "glass");
    // with the caustic light paths (the glass is a caster) and without them
    Scene scene;
    glass_scene(scene);
    scene.select_kernels(false);
    EXPECT_GT(render(scene, settings(2, false)).stats.caustic_casters, 0u);
}

TEST(PathBatch, MatchesTheScalarReferenceThroughGlassWithoutCausticTracing) {
    check_scene([](Scene& s) { glass_scene(s); }, "glass, no caustic tracing", false);
}

TEST(PathBatch, MatchesTheScalarReferenceOnPreviewSurfacesBesideGlass) {
    // a glossy preview floor under the glass ball, in the preview lanes (diffuse_lanes.h):
    // the caustic light tracing reads their reverse densities at every rough vertex after
    // the first (floor, ball, ball, floor)
    check_scene(
        [](Scene& s) {
            glass_scene_unlit(s);
            Material floor{Spectrum(0.6f, 0.5f, 0.4f), Spectrum(0.f)};
            floor.preview = true;
            floor.roughness = 0.35f;
            floor.metallic = 0.3f;
            s.set_materials({floor, smooth_glass()});
            s.add_light(sphere_light(Vec3(0.25f, 1.4f, -0.1f), 0.25f, Spectrum(12.f, 11.f, 9.f)));
            s.commit();
            EXPECT_NE(s.constant_preview(0), nullptr);
        },
        "preview floor, glass");
}
