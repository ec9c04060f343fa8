#pragma once
/// \file Render settings, results and statistics shared by all integrators.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace cmlt {

/// Settings of one frame. Each field: default, valid range.
struct RenderSettings {
    int width = 640;               ///< image width in pixels, >= 1
    int height = 480;              ///< image height in pixels, >= 1
    int spp = 16;                  ///< samples per pixel, >= 1
    int max_depth = 64;            ///< max scattering events (pbrt): 1 = direct lighting, >= 1
    uint64_t seed = 0;             ///< RNG seed; same seed -> same image at any thread count
    int threads = 0;               ///< worker threads, 0 = all cores, >= 0
    std::string integrator = "pt"; ///< "pt" (path tracing with NEE + MIS)

    /// Throws SettingsError naming the bad field.
    void validate() const;
};

struct RenderStats {
    double time_s = 0;
    uint64_t samples = 0;       ///< pixel samples taken
    uint64_t camera_rays = 0;
    uint64_t shadow_rays = 0;
    uint64_t rays = 0;          ///< every BVH query (camera + bounce + shadow)
    double rays_per_s = 0;
    uint64_t nan_samples = 0;   ///< non-finite samples dropped by the film
    int first_nan_x = -1, first_nan_y = -1;
    int64_t first_nan_sample = -1;
    int threads = 0;
    std::string integrator;
    int spp = 0;
    uint64_t seed = 0;
};

struct RenderResult {
    int width = 0, height = 0;
    std::vector<float> image;     ///< (H, W, 3), row 0 at the top
    std::vector<float> variance;  ///< (H, W, 3), sample variance of the pixel mean
    bool cancelled = false;
    RenderStats stats;
};

/// Called from the calling thread between chunks with (done, total) samples per pixel;
/// return false to stop after the current chunk.
using ProgressCallback = std::function<bool(uint64_t done, uint64_t total)>;

}  // namespace cmlt
