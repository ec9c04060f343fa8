#pragma once
/// \file The frame render loop: tiles over oneTBB, chunks of samples, progress/cancel.
#include "integrators/common/render_settings.h"
#include "scene/scene.h"

namespace cmlt {

/// Render one frame. Commits the scene first if it has uncommitted edits. Throws
/// SettingsError / SceneError on bad input. `progress` runs on the calling thread.
RenderResult render(Scene& scene, const RenderSettings& settings,
                    const ProgressCallback& progress = {});

}  // namespace cmlt
