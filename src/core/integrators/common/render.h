#pragma once
/// \file render(): one frame with the integrator the settings name (the table of
/// integrators, base/integrator.h).
#include "base/integrator.h"
#include "integrators/common/error_target.h"
#include "integrators/common/render_settings.h"
#include "scene/scene.h"

#include <cstddef>

namespace cmlt {

/// Render one frame. Commits the scene first if it has uncommitted edits. Throws
/// SettingsError / SceneError on bad input. `progress` runs on the calling thread.
RenderResult render(Scene& scene, const RenderSettings& settings, const ProgressCallback& progress = {});
/// The same, calling `on_estimate` with each estimate of a frame with a target error
/// (RenderSettings.target_error; error_target.h's EstimateCallback), as it is made.
RenderResult render(Scene& scene, const RenderSettings& settings, const ProgressCallback& progress,
                    const EstimateCallback& on_estimate);

/// The integrators by name ("pt", "bdpt", "pssmlt", "cmlt"), `count` rows.
const IntegratorEntry* integrator_table(size_t* count);

/// The image of a pssmlt/cmlt frame rendered in parts (RenderSettings::partial): the
/// parts' splat sums added exactly, b merged from the bootstrap and the chains in chain
/// order (parts sorted by their first chain, covering every chain once), developed with
/// `direct` (the direct pass's mean (H, W, 3) assembled from the parts' rows; empty
/// without one) — bit for bit the image of the frame rendered in one process.
/// stats.mlt.{b, b_stderr, mutations, clamped_splats} are set.
RenderResult combine_mlt_parts(int width, int height, const std::vector<const MltPart*>& parts,
                               const std::vector<float>& direct);

}  // namespace cmlt
