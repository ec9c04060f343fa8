#include "integrators/common/render_settings.h"

#include "util/error.h"

#include <cmath>

namespace cmlt {

void RenderSettings::validate() const {
    if (width < 1) CMLT_THROW(SettingsError, "RenderSettings.width must be >= 1, got " << width);
    if (height < 1) CMLT_THROW(SettingsError, "RenderSettings.height must be >= 1, got " << height);
    if (int64_t(width) * int64_t(height) > (int64_t(1) << 31))
        CMLT_THROW(SettingsError, "RenderSettings.width * height is too large (" << width << " x "
                                                                               << height << ")");
    if (spp < 1) CMLT_THROW(SettingsError, "RenderSettings.spp must be >= 1, got " << spp);
    if (!(time_budget >= 0.0) || !std::isfinite(time_budget))
        CMLT_THROW(SettingsError, "RenderSettings.time_budget must be >= 0 seconds, got " << time_budget);
    if (max_depth < 1)
        CMLT_THROW(SettingsError, "RenderSettings.max_depth must be >= 1, got " << max_depth);
    if (threads < 0) CMLT_THROW(SettingsError, "RenderSettings.threads must be >= 0, got " << threads);
    if (integrator != "pt" && integrator != "bdpt" && integrator != "pssmlt" && integrator != "cmlt")
        CMLT_THROW(SettingsError, "RenderSettings.integrator: unknown integrator '"
                                      << integrator << "' (available: 'pt', 'bdpt', 'pssmlt', 'cmlt')");
    if (tries < 1 || tries > 64)
        CMLT_THROW(SettingsError, "RenderSettings.tries must be in [1, 64], got " << tries);
    if (inner_length < 1)
        CMLT_THROW(SettingsError, "RenderSettings.inner_length must be >= 1, got " << inner_length);
    if (inner != "seed" && inner != "mtm" && inner != "bundle")
        CMLT_THROW(SettingsError, "RenderSettings.inner: unknown inner rule '"
                                      << inner << "' (available: 'seed', 'mtm', 'bundle')");
    if (mlt_path_sampler != "pt" && mlt_path_sampler != "bdpt")
        CMLT_THROW(SettingsError, "RenderSettings.mlt_path_sampler: unknown path sampler '"
                                      << mlt_path_sampler << "' (available: 'bdpt', 'pt')");
    if (importance != "pixel" && importance != "luminance")
        CMLT_THROW(SettingsError, "RenderSettings.importance: unknown importance '"
                                      << importance << "' (available: 'pixel', 'luminance')");
    if (pilot_spp < 1 || pilot_spp > 64)
        CMLT_THROW(SettingsError, "RenderSettings.pilot_spp must be in [1, 64], got " << pilot_spp);
    if (!(direct_fraction >= 0.0 && direct_fraction <= 0.9))
        CMLT_THROW(SettingsError, "RenderSettings.direct_fraction must be in [0, 0.9], got " << direct_fraction);
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
