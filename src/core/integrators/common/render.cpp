// render() and the integrator table; see render.h.
#include "integrators/common/render.h"

#include "integrators/bdpt/bdpt_integrator.h"
#include "integrators/cmlt/cmlt_integrator.h"
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

RenderResult render(Scene& scene, const RenderSettings& settings, const ProgressCallback& progress) {
    settings.validate();
    if (!scene.has_camera()) throw SceneError("render: the scene has no camera (call set_camera)");
    if (scene.dirty()) scene.commit();
    for (const IntegratorEntry& e : k_integrators)
        if (settings.integrator == e.name) return e.render(scene, settings, progress);
    CMLT_THROW(SettingsError, "RenderSettings.integrator: unknown integrator '" << settings.integrator << "'");
}

}  // namespace cmlt
