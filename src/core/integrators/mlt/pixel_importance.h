#pragma once
/// \file The importance function of the Metropolis chains (pssmlt, cmlt).
///
/// MLT's chains visit states x in proportion to a target f*(x); any f* > 0 wherever the
/// contribution is non-zero gives an unbiased image, because each splat adds L(x)/f*(x)
/// (times b = E[f*]; DESIGN.md §2). Which f* is used decides where the work goes:
///
///  * "luminance" (Veach; Kelemen et al.): f* = Y(L). The chains spend time ∝ brightness.
///    A directly visible lamp of a few pixels can hold most of the image's energy
///    (sequences/caustic_glass at frame 1: ten light pixels carry 77 % of it) and then
///    eats most of the mutations, while the rest of the frame stays noisy and blotchy.
///  * "pixel" (default; the arbitrary-importance form of Hoberock & Hart 2010, the
///    "two-stage" MLT of Mitsuba 0.5): f* = Y(L) / P(pixel(x)), P a smooth estimate of the
///    pixel's brightness. The chains then cover the image about uniformly, and inside
///    a pixel they still follow the contribution — light through a slit, caustics.
///
/// P comes from a pilot pass of the path tracer (`pilot_spp` samples per pixel, keyed by
/// the seed like every stream, so consecutive frames of a static shot get the same P),
/// made robust before use:
///   1. fireflies: a pixel's luminance is clamped to the largest of its 8 neighbours
///      (an isolated outlier is noise of a 1-spp estimate; a lamp covers neighbours);
///   2. blur: the separable [1 2 1] / 4 tent, twice (a 5×5 footprint);
///   3. floor: P ≥ k_floor · mean(P), so dark pixels (or caustics the pilot missed) get
///      at most 1 / k_floor times their fair share of mutations;
///   4. an all-black pilot (nothing lit, or nothing the path tracer finds) gives P = 1:
///      the luminance target; so does a pilot that lights fewer than k_min_lit_fraction
///      of the pixels. That is a dark scene whose light the pilot finds only now and then
///      (sequences/door_ajar at frame 1, 1 spp: 14-27 of 4,096 pixels lit), and its P is
///      a few blobs around chance hits that survived steps 1-2, with every other pixel at
///      the floor: f* is then 1/k_floor = 20 times Y almost everywhere and far less in
///      the blobs for no reason (b came out 13-19 times the luminance target's), the
///      chains hardly visit the blobs, each visit splats that much more, and a typical
///      render comes out dark — the estimator is consistent but heavy-tailed. Measured
///      on door_ajar frame 1, 64x64, 350 evaluations per pixel, pssmlt, seeds 0 and 2-5
///      (seed 1's pilot is black): mean brightness 0.84 of bdpt on average with the
///      blobs, each seed 0.75-0.89 of the luminance-target render with the same seed;
///      the luminance target 1.00 over seeds 0-5. Pilots of 64 spp (rendered apart and
///      given as RenderSettings::pilot, seeds 0 and 2-5) gave 0.97 (depths >= 0) and
///      1.03 (depths >= 2 only: what the chains render beside the direct pass; a
///      1-spp pilot of depths >= 2 changed nothing on door_ajar — its chance hits are
///      indirect light too — and made chains stick on the caustic of
///      tests/python/integrators/test_pssmlt_bdpt.py, so the pilot renders every depth).
/// The pilot's samples count against the frame's budget of path evaluations.
#include "math/vec.h"

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace cmlt {

class Scene;
struct RenderSettings;
struct PathCounters;

namespace mlt {

/// Per-pixel weights 1 / P of the "pixel" importance (see the file comment).
class PixelImportance {
public:
    /// Relative floor of P (step 3).
    static constexpr double k_floor = 0.05;
    /// Fewest pixels a pilot must light (luminance > 0), as a share of the image (step 4).
    static constexpr double k_min_lit_fraction = 0.1;

    PixelImportance() = default;  ///< luminance target (weight 1 everywhere)
    /// From a pilot image (H, W, 3 floats, scene-linear, row 0 at the top).
    PixelImportance(const std::vector<float>& pilot, int width, int height);

    bool uniform() const { return m_inv.empty(); }
    /// 1 / P(pixel) (1 for the luminance target).
    double weight(uint32_t pixel) const { return m_inv.empty() ? 1.0 : double(m_inv[pixel]); }
    /// P per pixel (empty for the luminance target), for stats and tests.
    std::vector<float> importance() const;
    int width() const { return m_width; }
    int height() const { return m_height; }

private:
    std::vector<float> m_inv;
    int m_width = 0, m_height = 0;
};

/// The importance of a frame for its settings: `importance` "luminance" → uniform;
/// "pixel" → from `settings.pilot` if given (it must be W×H×3), else from
/// render_pilot (direct_pass.h) at `pilot_spp`. `pilot_evaluations` (if given) receives the path
/// samples the pilot cost (0 when it was given or not needed).
std::shared_ptr<const PixelImportance> make_importance(const Scene& scene,
                                                       const RenderSettings& settings,
                                                       PathCounters& counters,
                                                       uint64_t* pilot_evaluations = nullptr);

}  // namespace mlt
}  // namespace cmlt
