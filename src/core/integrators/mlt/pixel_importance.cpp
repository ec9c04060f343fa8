// Pixel importance of the Metropolis chains; see pixel_importance.h.
#include "integrators/mlt/pixel_importance.h"

#include "integrators/common/render_settings.h"
#include "integrators/mlt/mlt_context.h"
#include "integrators/mlt/mlt_sampler.h"
#include "integrators/mlt/direct_pass.h"
#include "scene/scene.h"
#include "util/error.h"

#include <algorithm>
#include <cmath>

namespace cmlt::mlt {

namespace {

/// One pass of the separable [1 2 1] / 4 tent with clamped edges.
void tent(std::vector<double>& v, int w, int h) {
    std::vector<double> tmp(v.size());
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const double l = v[size_t(y) * w + size_t(std::max(x - 1, 0))];
            const double r = v[size_t(y) * w + size_t(std::min(x + 1, w - 1))];
            tmp[size_t(y) * w + x] = 0.25 * l + 0.5 * v[size_t(y) * w + x] + 0.25 * r;
        }
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const double u = tmp[size_t(std::max(y - 1, 0)) * w + x];
            const double d = tmp[size_t(std::min(y + 1, h - 1)) * w + x];
            v[size_t(y) * w + x] = 0.25 * u + 0.5 * tmp[size_t(y) * w + x] + 0.25 * d;
        }
}

}  // namespace

PixelImportance::PixelImportance(const std::vector<float>& pilot, int width, int height)
    : m_width(width), m_height(height) {
    const size_t n = size_t(width) * size_t(height);
    CMLT_CHECK_MSG(pilot.size() == 3 * n, "PixelImportance: pilot has " << pilot.size()
                                                                         << " values, expected " << 3 * n);
    std::vector<double> y(n);
    for (size_t i = 0; i < n; ++i) {
        const double v = target_luminance(Spectrum(pilot[3 * i], pilot[3 * i + 1], pilot[3 * i + 2]));
        y[i] = v;  // target_luminance: finite and >= 0
    }
    // 0. a pilot that lights too few pixels is noise, not an estimate: luminance target
    size_t lit = 0;
    for (double v : y) lit += v > 0.0 ? 1 : 0;
    if (double(lit) < k_min_lit_fraction * double(n)) return;
    // 1. fireflies: clamp to the brightest of the 8 neighbours
    std::vector<double> c(y);
    for (int py = 0; py < height; ++py)
        for (int px = 0; px < width; ++px) {
            double m = 0.0;
            bool any = false;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    if (dx == 0 && dy == 0) continue;
                    const int qx = px + dx, qy = py + dy;
                    if (qx < 0 || qy < 0 || qx >= width || qy >= height) continue;
                    m = std::max(m, y[size_t(qy) * width + qx]);
                    any = true;
                }
            if (any) c[size_t(py) * width + px] = std::min(y[size_t(py) * width + px], m);
        }
    // 2. blur
    tent(c, width, height);
    tent(c, width, height);
    // 3. floor, 4. black pilot → luminance target
    double mean = 0.0;
    for (double v : c) mean += v;
    mean /= double(std::max<size_t>(n, 1));
    if (!(mean > 0.0) || !std::isfinite(mean)) return;
    const double floor = k_floor * mean;
    // Scaled by mean(P): f* keeps the units of luminance (in an evenly lit frame f* = Y),
    // so b = E[f*] follows the lighting from frame to frame (the temporal smoothing of b
    // and its change detection rely on that). A splat L/f* = (L/Y) · P/mean(P) stays far
    // inside the SplatFilm's fixed-point range (film/splat_film.h) unless one pixel is ~10^6
    // times the mean and gets millions of splats; clamped splats are counted.
    m_inv.resize(n);
    for (size_t i = 0; i < n; ++i) m_inv[i] = float(mean / std::max(c[i], floor));
}

std::vector<float> PixelImportance::importance() const {
    std::vector<float> out(m_inv.size());
    for (size_t i = 0; i < m_inv.size(); ++i) out[i] = 1.f / m_inv[i];
    return out;
}

std::shared_ptr<const PixelImportance> make_importance(const Scene& scene, const RenderSettings& settings,
                                                       PathCounters& counters, uint64_t* pilot_evaluations) {
    if (pilot_evaluations) *pilot_evaluations = 0;
    if (settings.importance == "luminance") return std::make_shared<const PixelImportance>();
    const size_t n = size_t(settings.width) * size_t(settings.height) * 3;
    if (settings.pilot) {
        if (settings.pilot->size() != n)
            CMLT_THROW(SettingsError, "RenderSettings.pilot: " << settings.pilot->size()
                                          << " values for a " << settings.width << "x" << settings.height
                                          << " image (expected " << n << ")");
        return std::make_shared<const PixelImportance>(*settings.pilot, settings.width, settings.height);
    }
    const int spp = MltContext::pilot_spp(settings);
    if (spp == 0) return std::make_shared<const PixelImportance>();  // no chains to guide
    const std::vector<float> pilot = render_pilot(scene, settings, spp, counters);
    if (pilot_evaluations) *pilot_evaluations = uint64_t(spp) * uint64_t(settings.width) * uint64_t(settings.height);
    return std::make_shared<const PixelImportance>(pilot, settings.width, settings.height);
}

}  // namespace cmlt::mlt
