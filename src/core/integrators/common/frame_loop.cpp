// Frame-loop scaffolding shared by the integrators; see frame_loop.h.
#include "integrators/common/frame_loop.h"

#include "film/film.h"

#include <tbb/info.h>

namespace cmlt {

int frame_threads(const RenderSettings& s) {
    return s.threads > 0 ? s.threads : tbb::info::default_concurrency();
}

std::vector<Tile> image_tiles(int width, int height) {
    std::vector<Tile> tiles;
    for (int y = 0; y < height; y += k_tile_size)
        for (int x = 0; x < width; x += k_tile_size)
            tiles.push_back({x, y, std::min(x + k_tile_size, width), std::min(y + k_tile_size, height)});
    return tiles;
}

bool PassTarget::check(int done, double secs) {
    const size_t n = size_t(film.width()) * size_t(film.height()) * 3;
    std::vector<float> mean(n), var(n), robust(n);
    film.develop(mean.data(), var.data(), robust.data());
    reached = target.reached(double(done), secs,
                             estimate_from_variance(mean.data(), var.data(), robust.data(), film.width(),
                                                    film.height()));
    return reached;
}

RenderResult film_result(const Film& film, const FrameCounters& counters, const CycleRate& rate, double secs,
                         const RenderSettings& settings, int threads, int passes, bool cancelled,
                         PassTarget* target) {
    RenderResult res;
    res.width = settings.width;
    res.height = settings.height;
    const size_t n = size_t(res.width) * size_t(res.height) * 3;
    res.image.resize(n);
    res.variance.resize(n);
    res.robust.resize(n);
    film.develop(res.image.data(), res.variance.data(), res.robust.data());
    res.cancelled = cancelled;
    const ErrorValue err =
        estimate_from_variance(res.image.data(), res.variance.data(), res.robust.data(), res.width, res.height);
    res.error_estimate = err.relmse;
    res.error_stderr = err.stderr_;
    if (target) res.error_history = target->target.take_history();
    res.stop_reason = stop_reason(cancelled, target && target->reached, settings.time_budget > 0.0, secs,
                                  settings.time_budget);
    RenderStats& st = res.stats;
    fill_frame_stats(st, counters, rate, secs);
    st.nan_samples = film.nan_samples();
    int fx, fy;
    uint32_t fs;
    if (film.first_nan(&fx, &fy, &fs)) {
        st.first_nan_x = fx;
        st.first_nan_y = fy;
        st.first_nan_sample = fs;
    }
    st.threads = threads;
    st.integrator = settings.integrator;
    st.spp = passes;
    st.seed = settings.seed;
    return res;
}

}  // namespace cmlt
