#pragma once
/// \file What every Metropolis computation of one frame shares (pssmlt, cmlt, and the
/// carry-over evaluations of temporal/carry.h): the camera, both path samplers, the
/// importance function, and the PssmltTracer over them — built once, the same way
/// everywhere, so f* in one place is f* in every other bit for bit.
#include "analysis/scene_probes.h"
#include "cameras/camera.h"
#include "integrators/bdpt/bdpt_tracer.h"
#include "integrators/common/render_settings.h"
#include "integrators/mlt/pixel_importance.h"
#include "integrators/mlt/pssmlt_tracer.h"
#include "integrators/path/caustic_light_tracing.h"
#include "integrators/path/path_tracer.h"
#include "lights/emission_guide.h"
#include "scene/scene.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>

namespace cmlt::mlt {

struct MltContext {
    /// Renders the pilot of the "pixel" importance unless settings.pilot holds it;
    /// its rays go to `counters`.
    MltContext(const Scene& scene, const RenderSettings& s, PathCounters& counters)
        : filter(PixelFilter::from_settings(s.pixel_filter, s.filter_radius)),
          camera(scene.camera_desc(), s.width, s.height), pt(scene, s.max_depth, min_depth(s)),
          bdpt(scene, camera, s.width, s.height, s.max_depth, filter.margin()),
          importance(make_importance(scene, s, counters, &pilot_rendered)),
          tracer(s.mlt_path_sampler == "bdpt" ? PssmltTracer(bdpt, camera, s.width, s.height, min_depth(s),
                                                                     camera_technique(scene, s))
                                              : PssmltTracer(pt, camera, s.width, s.height)),
          partition(scene, partitioned(s) ? PathPart::caustic : PathPart::all, s.mlt_sds == "direct") {
        // the caustic paths the direct pass's light tracing makes are its own (the same
        // tracer as DirectPass's: camera, film window, depth; path_partition.h)
        if (traced_to_direct(s))
            partition.set_traced(
                CausticLightTracing(scene, camera, s.width, s.height, filter.margin(), s.max_depth).traced_lights());
        pt.set_partition(&partition);
        bdpt.set_partition(&partition);
        // the chains' light subpaths aimed at the casters (bdpt_tracer.h; auto below)
        if (!chainless(s)) {
            double guiding = s.emission_guiding;
            if (guiding < 0.0) {
                const EmissionGuide guide(scene);
                caster_coverage = cmlt::caster_coverage(scene, guide);  // the free function
                guiding = guide.active() && caster_coverage < k_auto_guide_coverage ? k_auto_guiding : 0.0;
            }
            if (guiding > 0.0) bdpt.set_emission_guiding(float(guiding));
        }
        tracer.set_importance(importance.get());
        tracer.set_filter(&filter);
        // the chains' film position follows the frame's key map, or its film offset
        FilmMap map;
        map.offset = Vec2(float(s.film_offset_x), float(s.film_offset_y));
        if (s.pixel_keys && s.pixel_keys->size() == size_t(s.width) * size_t(s.height)) {
            pixel_of_key.resize(s.pixel_keys->size());
            for (size_t p = 0; p < pixel_of_key.size(); ++p) pixel_of_key[(*s.pixel_keys)[p]] = uint32_t(p);
            map.pixel_of_key = pixel_of_key.data();
            map.width = s.width;
            map.height = s.height;
            map.margin = filter.margin();
        }
        tracer.set_film_map(map);
    }
    MltContext(const MltContext&) = delete;
    MltContext& operator=(const MltContext&) = delete;

    /// Pilot samples per pixel: pilot_spp for the "pixel" importance (at most spp/8,
    /// at least 1), else 0.
    static int pilot_spp(const RenderSettings& s) {
        if (chainless(s)) return 0;
        return s.importance == "pixel" ? std::max(1, std::min(s.pilot_spp, s.spp / 8)) : 0;
    }
    /// RenderSettings::mlt_paths with auto resolved: "all" when direct_fraction is 0 (no
    /// direct pass: the chains render everything), else "caustics" where a material can
    /// be near-specular (`specular`), "none" where not (no caustic path exists). The
    /// budget functions below pass no scene (`specular` true: auto read as caustics).
    static std::string paths(const RenderSettings& s, bool specular = true) {
        if (s.mlt_paths != "auto") return s.mlt_paths;
        if (s.direct_fraction == 0.0) return "all";
        return specular ? "caustics" : "none";
    }
    /// `s` with mlt_paths resolved for this scene (paths()); the frame functions resolve
    /// it on entry.
    static RenderSettings resolve_paths(const Scene& scene, const RenderSettings& s) {
        RenderSettings out = s;
        if (out.mlt_paths == "auto") out.mlt_paths = paths(s, scene_may_be_specular(scene));
        return out;
    }
    /// The chains render a part of path space and the direct pass the rest of it, at
    /// every depth (mlt_paths caustics or none: path_partition.h).
    static bool partitioned(const RenderSettings& s) { return paths(s) != "all"; }
    /// No chains: the direct pass renders every path (mlt_paths none).
    static bool chainless(const RenderSettings& s) { return s.mlt_paths == "none"; }
    /// Does the direct pass render the light-traced caustics (path_partition.h), with pt's
    /// caustic light tracing, beside chains on the other caustic paths?
    static bool traced_to_direct(const RenderSettings& s) {
        return partitioned(s) && !chainless(s) && s.caustic_tracing && s.mlt_traced_caustics == "direct";
    }
    /// The direct pass's share of a frame's evaluations (RenderSettings::direct_fraction
    /// with auto resolved): k_direct_fraction_all when the chains render every longer
    /// path, k_direct_fraction_partitioned when they render the caustic ones (README,
    /// "Caustic paths only": equal-time study on caustic_glass and the Cornell box).
    static constexpr double k_direct_fraction_all = 0.3, k_direct_fraction_partitioned = 0.7;
    static double direct_fraction(const RenderSettings& s) {
        if (s.direct_fraction >= 0.0) return s.direct_fraction;
        return partitioned(s) ? k_direct_fraction_partitioned : k_direct_fraction_all;
    }
    /// Deepest path of the direct pass: 1 (depths 0 and 1) when the chains render every
    /// longer path, else max_depth (partitioned).
    static int direct_max_depth(const RenderSettings& s) {
        return partitioned(s) ? s.max_depth : std::min(1, s.max_depth);
    }
    /// Direct-pass samples per pixel of a sample budget: round(direct_fraction · spp),
    /// at least 1 when the share is > 0; 0 = no direct pass. (With a time budget the pass
    /// runs alongside the chains at the same share of evaluations: direct_pass.h.)
    static int direct_spp(const RenderSettings& s) {
        if (chainless(s)) return s.spp;
        const double f = direct_fraction(s);
        if (!(f > 0.0)) return 0;  // (refused when partitioned)
        return std::max(1, int(std::lround(f * double(s.spp))));
    }
    /// Path evaluations the pilot costs in the budget (whether rendered here or given).
    static uint64_t pilot_cost(const RenderSettings& s) {
        return uint64_t(pilot_spp(s)) * uint64_t(s.width) * uint64_t(s.height);
    }
    /// Path evaluations of the direct pass.
    static uint64_t direct_cost(const RenderSettings& s) {
        return uint64_t(direct_spp(s)) * uint64_t(s.width) * uint64_t(s.height);
    }
    /// Shortest path the chains render: 2 with a direct pass (a caustic path has two
    /// scattering vertices at least), else 0.
    static int min_depth(const RenderSettings& s) {
        return direct_fraction(s) > 0.0 || partitioned(s) ? 2 : 0;
    }
    /// q of the camera technique (mlt/technique.h) when auto chooses it: where a
    /// material can be near-specular (scene_may_be_specular) and the chains render the
    /// caustic paths alone (README, "The camera technique": on caustic_glass, 30 renders
    /// at 96x96 and 2 s, it lowered the median and the worst relMSE, and it cures
    /// caustic_sds's rare glint; q = 0.5 there had heavier tails than q = 0).
    static constexpr double k_auto_camera_technique = 0.7;
    /// Auto emission guiding of the chains (RenderSettings::emission_guiding negative):
    /// k_auto_guiding where the casters' cones cover less than k_auto_guide_coverage of
    /// the directions from the lights (lights/emission_guide.h, caster_coverage: a light
    /// subpath heads for a caster that rarely without the guide, so the guide multiplies
    /// the bootstrap's and the large steps' caustic paths by g / coverage ≥ 5), else off.
    /// README, "Caustics in bdpt": caustic_glass (coverage 0.045) and caustic_lsdse
    /// (0.023) gain; bulb_room (a mirror and a slab beside the bulb, 0.178) gained
    /// nothing and its chains grew more concentrated (tests/python/hard, test05). The
    /// bound was set knowing those three values.
    static constexpr double k_auto_guiding = 0.5, k_auto_guide_coverage = 0.1;
    /// RenderSettings::mlt_camera_technique resolved: negative = auto (0 for the pt
    /// path sampler, which has no techniques, and with the chains on every path, where
    /// the technique kept chains longer on a caustic: tests/python/integrators/
    /// test_pssmlt_bdpt.py's occupancy bound failed at q = 0.5).
    static double camera_technique(const Scene& scene, const RenderSettings& s) {
        if (s.mlt_path_sampler != "bdpt") return 0.0;
        if (s.mlt_camera_technique >= 0.0) return s.mlt_camera_technique;
        return partitioned(s) && scene_may_be_specular(scene) ? k_auto_camera_technique : 0.0;
    }
    /// Do the chains have any paths to render (not with a direct pass and max_depth 1,
    /// not chainless)?
    static bool chains_needed(const RenderSettings& s) { return !chainless(s) && s.max_depth >= min_depth(s); }
    /// Path evaluations left for bootstrap and chains: spp·W·H minus the pilot and the
    /// direct pass (≥ 2).
    static uint64_t evaluation_budget(const RenderSettings& s) {
        const uint64_t total = uint64_t(s.spp) * uint64_t(s.width) * uint64_t(s.height);
        const uint64_t used = std::min(total, pilot_cost(s) + direct_cost(s));
        return std::max<uint64_t>(2, total - used);
    }

    PixelFilter filter;  ///< the chains' splats (the direct pass filters its own samples)
    Camera camera;
    PathTracer pt;
    BdptTracer bdpt;
    uint64_t pilot_rendered = 0;  ///< pilot samples rendered here (0 if given or not needed)
    std::vector<uint32_t> pixel_of_key;  ///< the key map's inverse (the tracer's FilmMap points here)
    /// caster_coverage of the scene where auto guiding asked for it, else −1
    double caster_coverage = -1.0;
    std::shared_ptr<const PixelImportance> importance;
    PssmltTracer tracer;
    /// The chains' class of paths (every path unless partitioned).
    PathPartition partition;
};

}  // namespace cmlt::mlt
