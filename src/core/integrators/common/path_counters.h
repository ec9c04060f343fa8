#pragma once
/// \file Rays and samples a path-sampling routine traced, summed per task and then into
/// the frame's FrameCounters (frame_loop.h); integer sums, so order-independent.
#include <cstdint>

namespace cmlt {

struct PathCounters {
    uint64_t camera_rays = 0;
    uint64_t shadow_rays = 0;
    uint64_t rays = 0;     ///< every BVH query (camera + bounce + shadow)
    uint64_t samples = 0;  ///< path samples (a pixel sample, a Metropolis evaluation)

    PathCounters& operator+=(const PathCounters& o) {
        camera_rays += o.camera_rays;
        shadow_rays += o.shadow_rays;
        rays += o.rays;
        samples += o.samples;
        return *this;
    }
};

}  // namespace cmlt
