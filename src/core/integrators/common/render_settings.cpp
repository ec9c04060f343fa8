#include "integrators/common/render_settings.h"

#include "util/error.h"

namespace cmlt {

void RenderSettings::validate() const {
    if (width < 1) CMLT_THROW(SettingsError, "RenderSettings.width must be >= 1, got " << width);
    if (height < 1) CMLT_THROW(SettingsError, "RenderSettings.height must be >= 1, got " << height);
    if (int64_t(width) * int64_t(height) > (int64_t(1) << 31))
        CMLT_THROW(SettingsError, "RenderSettings.width * height is too large (" << width << " x "
                                                                               << height << ")");
    if (spp < 1) CMLT_THROW(SettingsError, "RenderSettings.spp must be >= 1, got " << spp);
    if (max_depth < 1)
        CMLT_THROW(SettingsError, "RenderSettings.max_depth must be >= 1, got " << max_depth);
    if (threads < 0) CMLT_THROW(SettingsError, "RenderSettings.threads must be >= 0, got " << threads);
    if (integrator != "pt" && integrator != "bdpt" && integrator != "pssmlt")
        CMLT_THROW(SettingsError, "RenderSettings.integrator: unknown integrator '"
                                      << integrator << "' (available: 'pt', 'bdpt', 'pssmlt')");
    if (!(sigma > 0.0 && sigma <= 1.0))
        CMLT_THROW(SettingsError, "RenderSettings.sigma must be in (0, 1], got " << sigma);
    if (!(large_step_probability >= 0.0 && large_step_probability <= 1.0))
        CMLT_THROW(SettingsError, "RenderSettings.large_step_probability must be in [0, 1], got "
                                      << large_step_probability);
    if (chains < 1) CMLT_THROW(SettingsError, "RenderSettings.chains must be >= 1, got " << chains);
    if (bootstrap_samples < 1)
        CMLT_THROW(SettingsError,
                   "RenderSettings.bootstrap_samples must be >= 1, got " << bootstrap_samples);
}

}  // namespace cmlt
