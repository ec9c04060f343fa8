#pragma once
/// \file render(): one frame with the integrator the settings name (the table of
/// integrators, base/integrator.h).
#include "base/integrator.h"
#include "integrators/common/render_settings.h"
#include "scene/scene.h"

#include <cstddef>

namespace cmlt {

/// Render one frame. Commits the scene first if it has uncommitted edits. Throws
/// SettingsError / SceneError on bad input. `progress` runs on the calling thread.
RenderResult render(Scene& scene, const RenderSettings& settings, const ProgressCallback& progress = {});

/// The integrators by name ("pt", "bdpt", "pssmlt", "cmlt"), `count` rows.
const IntegratorEntry* integrator_table(size_t* count);

}  // namespace cmlt
