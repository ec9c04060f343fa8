// render() and the integrator table; see render.h.
#include "integrators/common/render.h"

#include "film/filter.h"
#include "integrators/bdpt/bdpt_integrator.h"
#include "integrators/cmlt/cmlt_integrator.h"
#include "integrators/mlt/mlt_context.h"
#include "integrators/mlt/mlt_frame.h"
#include "integrators/path/path_integrator.h"
#include "integrators/pssmlt/pssmlt_integrator.h"
#include "util/error.h"

#include <cstring>
#include <iterator>

namespace cmlt {

namespace {

constexpr IntegratorEntry k_integrators[] = {
    {"pt", render_pt},
    {"bdpt", render_bdpt},
    {"pssmlt", render_pssmlt},
    {"cmlt", render_cmlt},
};

}  // namespace

const IntegratorEntry* integrator_table(size_t* count) {
    *count = std::size(k_integrators);
    return k_integrators;
}

RenderResult render(Scene& scene, const RenderSettings& settings, const ProgressCallback& progress,
                    const EstimateCallback& on_estimate) {
    ScopedEstimateListener listen(on_estimate);
    return render(scene, settings, progress);
}

RenderResult render(Scene& scene, const RenderSettings& settings, const ProgressCallback& progress) {
    settings.validate();
    if (!scene.has_camera()) throw SceneError("render: the scene has no camera (call set_camera)");
    if (scene.dirty()) scene.commit();
    if (settings.partial && settings.integrator == "bdpt")
        throw SettingsError("RenderSettings.partial: bdpt frames do not split (its light-tracing "
                            "splats reach every pixel of a pass); render them whole");
    // the material kernels of this render (analysis/kernel_select.h); auto again after it
    struct KernelScope {
        Scene& scene;
        ~KernelScope() { scene.select_kernels(false); }
    } kernels{scene};
    scene.select_kernels(settings.kernel == "general");
    // "auto" is not an integrator: the frame loop resolves it from the shot's effects
    // before the core sees it; called on its own the core has no shot to analyse and
    // renders auto as pt (the settings table's doc)
    const RenderSettings* use = &settings;
    RenderSettings as_pt;
    if (settings.integrator == "auto") {
        as_pt = settings;
        as_pt.integrator = "pt";
        use = &as_pt;
    }
    // a pssmlt/cmlt frame whose chains would start from a handful of paths (the start
    // probe, RenderSettings::mlt_min_starts) is rendered without chains: mlt_paths none
    RenderSettings as_chainless;
    mlt::StartProbe starts;
    const bool probed = mlt::start_probe_applies(scene, *use);
    if (probed) {
        starts = mlt::probe_starts(scene, *use);
        if (starts.too_few) {
            as_chainless = *use;
            as_chainless.mlt_paths = "none";
            use = &as_chainless;
        }
    }
    // a pssmlt/cmlt frame without chains (mlt_paths none, or auto on a scene without
    // near-specular materials) rendered by BDPT where chainless_integrator asks for it:
    // the frame is then `--integrator bdpt`'s, bit for bit (the frame loop resolves
    // chainless_integrator auto from the shot's effects; here auto is pt)
    RenderSettings as_bdpt;
    if ((use->integrator == "pssmlt" || use->integrator == "cmlt") && use->chainless_integrator == "bdpt" &&
        mlt::MltContext::resolve_paths(scene, *use).mlt_paths == "none") {
        if (use->partial)
            throw SettingsError("RenderSettings.chainless_integrator: bdpt renders this frame (it has "
                                "no chains) and bdpt frames do not split; render it whole or use pt");
        as_bdpt = *use;
        as_bdpt.integrator = "bdpt";
        use = &as_bdpt;
    }
    const PixelFilter filter = PixelFilter::from_settings(settings.pixel_filter, settings.filter_radius);
    for (const IntegratorEntry& e : k_integrators)
        if (use->integrator == e.name) {
            RenderResult res = e.render(scene, *use, progress);
            res.stats.pixel_filter = filter.name();
            res.stats.filter_radius = filter.radius();
            res.stats.sampler = pixel_sequence_name(pixel_sequence(*use));
            if (probed) {
                res.stats.mlt_expected_starts = starts.expected;
                res.stats.mlt_too_few_starts = starts.too_few;
                res.stats.rays += starts.counters.rays;
                res.stats.camera_rays += starts.counters.camera_rays;
                res.stats.shadow_rays += starts.counters.shadow_rays;
            }
            return res;
        }
    CMLT_THROW(SettingsError, "RenderSettings.integrator: unknown integrator '" << settings.integrator << "'");
}

RenderResult combine_mlt_parts(int width, int height, const std::vector<const MltPart*>& parts,
                               const std::vector<float>& direct) {
    return mlt::combine_parts(width, height, parts, direct);
}

}  // namespace cmlt
