#pragma once
/// \file Render settings, results and statistics shared by all integrators.
///
/// The settings table below is the one source of every setting: the fields of
/// RenderSettings, their defaults and ranges (RenderSettings::validate), the bindings
/// (src/bindings/bind_render.cpp, which also export the table as
/// `cmlt._core.settings_table()`), and from there the Python side: the command-line
/// flags, the stage attribute lookup and its checks (cmlt.settings) and the USD schema
/// (plugins/usd/cmltSchemas/resources/*.usda, written by `python -m
/// cmlt.settings.usd_schema --write`; tests/python/settings checks they have not drifted).
#include "sampling/rng.h"

#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace cmlt {

namespace mlt {
struct ChainStates;  // integrators/mlt/chain_state.h
}

namespace settings_limits {
constexpr int k_int_max = std::numeric_limits<int>::max();
constexpr double k_inf = std::numeric_limits<double>::infinity();
}  // namespace settings_limits

// The settings table. One row per setting, one macro per kind:
//
//   INT  (name, default, min, max,           attribute, flag, doc)   int, [min, max]
//   REAL (name, default, min, max, min_open, attribute, flag, doc)   double, [min, max]
//                                                                     or (min, max]; finite
//   U64  (name, default,                     attribute, flag, doc)   uint64_t, any value
//   BOOL (name, default,                     attribute, flag, doc)   bool
//   TOKEN(name, default, allowed,            attribute, flag, doc)   std::string, one of the
//                                                                     space-separated tokens
//
// attribute: the CmltRenderSettingsAPI attribute on a UsdRender.Settings prim ("": not a
// stage setting). flag: the `cmlt render` flag, its aliases after '|', then its metavar
// ("--time-budget|--time SECONDS"); a BOOL's flag sets the opposite of its default;
// "": no flag. doc: one phrase, used by the schema, the flag's help and the bindings.
//
// Ranges, where the layers used to disagree (the table is now the only statement):
// * seed: any uint64. The core keys its counter-based streams by all 64 bits and the
//   frame loop's per-frame seeds (seed_per_frame) use them; the former 2^31 - 1 cap of
//   the stage and the flags came only from the schema's `int` type (now uint64; stages
//   authoring an int seed still read).
// * tries 1..64, pilot_spp 1..64, max_depth 1..1024, inner_length 1..10^6: the stage's
//   ranges, which the core already enforced for tries and pilot_spp; the flags checked
//   only the lower bound and the core left max_depth and inner_length open. A value the
//   stage refuses is now refused by every layer.
// * width, height 1..65536 (the --res flag's limit; the stage and the core had none
//   but the product's, which validate still checks).
//
// Defaults: pbrt-v4's published MLT defaults for sigma, large_step_probability, chains
// and bootstrap_samples (shared/NOTES.md); tries and inner_length from the coherent-MLT
// parameter study (README.md, tests/bench/cmlt_params.py).
// The table is laid out in columns by hand:
// clang-format off
#define CMLT_RENDER_SETTINGS(INT, REAL, U64, BOOL, TOKEN)                                    \
    TOKEN(integrator, "auto", "auto pt bdpt pssmlt cmlt", "cmlt:integrator",                \
          "--integrator",                                                                    \
          "light transport: auto (chosen per shot from the effects of its frames, "         \
          "cmlt.analysis.auto; the core alone, with no shot to analyse, renders it as pt), " \
          "pt (path tracing, NEE + MIS), bdpt (bidirectional), pssmlt "                      \
          "(primary-sample-space MLT), cmlt (coherent MLT)")                                 \
    INT(spp, 16, 1, settings_limits::k_int_max, "cmlt:spp", "--spp N",                       \
        "samples per pixel (pt, bdpt) or path evaluations per pixel (pssmlt, cmlt: "         \
        "mutations, bootstrap, pilot and direct pass included)")                             \
    REAL(time_budget, 0.0, 0.0, settings_limits::k_inf, false, "cmlt:timeBudget",            \
         "--time-budget|--time SECONDS",                                                     \
         "wall-clock seconds per frame, 0 = off; with a sample budget too, whichever "       \
         "comes first")                                                                      \
    U64(seed, 0, "cmlt:seed", "--seed S",                                                    \
        "shot seed, the same for every frame: random streams are keyed by (seed, chain or "  \
        "pixel, dimension), never by thread")                                                \
    INT(max_depth, 64, 1, 1024, "cmlt:maxDepth", "--max-depth N",                            \
        "scattering events per path, counted as pbrt does (1 = direct light only); paths "   \
        "end by Russian roulette long before")                                               \
    REAL(sigma, 0.01, 0.0, 1.0, true, "cmlt:sigma", "--sigma S",                             \
         "pssmlt/cmlt: standard deviation of the Gaussian small step in primary sample "     \
         "space (cmlt's lens perturbation: sigma * max(width, height) pixels)")              \
    INT(tries, 2, 1, 64, "cmlt:tries", "--tries K",                                          \
        "cmlt: k, candidates per inner step, drawn and traced as one coherent bundle")       \
    INT(inner_length, 4, 1, 1000000, "cmlt:innerLength", "--inner-length M",                 \
        "cmlt: m, inner steps after each outer (large) step")                                \
    REAL(large_step_probability, 0.3, 0.0, 1.0, false, "cmlt:largeStepProbability",          \
         "--large-step-probability P",                                                       \
         "pssmlt/cmlt: probability of an independent (large) step of the outer chain")       \
    INT(chains, 1000, 1, settings_limits::k_int_max, "cmlt:chains", "--chains N",            \
        "pssmlt/cmlt: Markov chains per frame (fixed, so that the image does not depend on " \
        "the thread count)")                                                                 \
    INT(bootstrap_samples, 0, 0, settings_limits::k_int_max, "cmlt:bootstrapSamples",        \
        "--bootstrap-samples N",                                                             \
        "pssmlt/cmlt: large-step samples estimating the normalisation b and seeding the "    \
        "chains, counted in the sample budget (at most half of it is used); 0 = auto: "      \
        "100000, or as many as give about one sample that carries light per chain where "    \
        "fewer than one in a hundred do (a probe of 16384 samples counts them), up to a "   \
        "quarter of the budget")                                                             \
    TOKEN(inner, "bundle", "seed mtm bundle", "cmlt:inner", "--inner",                  \
          "cmlt inner rule: bundle (multiple-proposal MH, Calderhead 2014; exact), mtm "     \
          "(multiple-try Metropolis, Liu et al. 2000; exact), seed (the seminar's 2k "       \
          "splats; biased, for comparison only)")                                            \
    TOKEN(importance, "pixel", "pixel luminance", "cmlt:importance", "--importance",    \
          "pssmlt/cmlt importance: pixel (luminance over a smoothed pilot image's pixel "    \
          "brightness: the chains cover the image about evenly) or luminance (classic MLT)") \
    REAL(direct_fraction, -1.0, -1.0, 0.9, false, "cmlt:directFraction", "--direct-fraction F", \
         "pssmlt/cmlt: share of the path evaluations spent on the path-traced direct pass "  \
         "(with mlt_paths all: emitters seen directly and direct light, the chains render "  \
         "longer paths; with caustics: every path but the caustic ones); 0 = the chains "    \
         "render everything (mlt_paths auto then means all; refused with caustics); "        \
         "negative = auto (0.3 with mlt_paths all, " \
         "0.7 with caustics)")                                                               \
    TOKEN(mlt_paths, "auto", "auto all caustics none", "cmlt:mltPaths", "--mlt-paths",       \
          "pssmlt/cmlt: the paths the chains render (integrators/common/path_partition.h): " \
          "all (every path of depth >= 2; the direct pass renders depths 0 and 1), "         \
          "caustics (only caustic paths, L S+ D...E: light reaching a rough surface through " \
          "a near-specular chain; the direct pass path-traces every other path), none (no "  \
          "chains: the direct pass renders everything), auto (caustics where a material "    \
          "can be near-specular, else none; all with direct_fraction 0)")                                                \
    TOKEN(mlt_sds, "direct", "direct chains", "cmlt:mltSds", "--mlt-sds",                    \
          "pssmlt/cmlt with mlt_paths caustics: what renders the caustics seen through a "   \
          "near-specular chain, E S+ D S+ L (one rough vertex): direct (the path-traced "    \
          "direct pass; default) or chains (lower error in most frames, but a chain on such " \
          "a path can sit on an island it cannot leave, and a frame then gets a blob)")      \
    TOKEN(mlt_traced_caustics, "direct", "direct chains", "cmlt:mltTracedCaustics",          \
          "--mlt-traced-caustics",                                                           \
          "pssmlt/cmlt with mlt_paths caustics: what renders the caustic paths the path "    \
          "tracer's caustic light tracing makes (the light next to a mirror or glass bounce " \
          "is a finite, non-Dirac light; the camera's first hit rough): direct (the direct " \
          "pass, camera paths MIS-weighted against light paths as the pt integrator; "      \
          "default) or chains (the rule before; chains keep dome and distant lights' "       \
          "caustics and glossy chains either way)")                                          \
    INT(mlt_min_starts, 64, 0, settings_limits::k_int_max, "cmlt:mltMinStarts",               \
        "--mlt-min-starts N",                                                                \
        "pssmlt/cmlt with mlt_paths auto on a frame with near-specular materials and an "    \
        "auto bootstrap size: a probe of 16384 samples (keys of their own) predicts how "    \
        "many of the bootstrap's samples carry light for the chains; below N the frame is "  \
        "rendered without chains, as mlt_paths none (chains resampled from a handful of "    \
        "paths copy them, and the path-traced frame is the faster one there); 0 = off")      \
    TOKEN(chainless_integrator, "auto", "auto pt bdpt", "cmlt:chainlessIntegrator",         \
          "--chainless-integrator",                                                          \
          "pssmlt/cmlt: what renders a frame that has no chains (mlt_paths none, or auto on " \
          "a frame without near-specular materials): pt (the direct pass: path tracing), "   \
          "bdpt (bidirectional, as --integrator bdpt), or auto (bdpt where the shot's auto "  \
          "integrator picks it for indirect hot spots, else pt; resolved by the frame loop, " \
          "cmlt.shot.analyse; the core alone renders it as pt)")                             \
    INT(pilot_spp, 1, 1, 64, "cmlt:pilotSpp", "--pilot-spp N",                               \
        "pssmlt/cmlt: path-traced samples per pixel of the pixel importance's pilot image "  \
        "(at most spp/8; counted in the budget)")                                            \
    INT(width, 640, 1, 65536, "", "",                                                        \
        "image width in pixels (the stage's UsdRender resolution or --res)")                 \
    INT(height, 480, 1, 65536, "", "",                                                       \
        "image height in pixels (the stage's UsdRender resolution or --res)")                \
    INT(threads, 0, 0, settings_limits::k_int_max, "", "--threads N",                        \
        "worker threads, 0 = all cores; the image does not depend on it")                    \
    BOOL(caustic_tracing, true, "", "--no-caustic-tracing",                                  \
         "pt: also trace the caustics it cannot find (light reaching a rough surface "       \
         "through a mirror or glass bounce) from the lights, MIS-weighted against its "       \
         "camera paths (the same image in expectation, less noise); off: camera paths only")  \
    REAL(emission_guiding, -1.0, -1.0, 0.95, false, "cmlt:emissionGuiding", "--emission-guiding G", \
         "bdpt, pssmlt and cmlt: share of a finite light's subpaths emitted toward the "    \
         "mirror and glass objects (their bounding spheres) rather than by the light's own " \
         "sampling, so light tracing finds the caustics they throw (the same image in "      \
         "expectation; lights/emission_guide.h); 0 = off; negative (the default) = auto: "   \
         "0.5 for bdpt, and for the chains of pssmlt and cmlt where the casters cover "     \
         "under a tenth of the lights' directions (README, Caustics in bdpt); no effect "   \
         "without such objects")                                                            \
    BOOL(packets, true, "", "--no-packets",                                                  \
         "pt and cmlt: trace a batch's or bundle's rays (camera rays, bounces, shadow rays) "  \
         "as Embree packets; off: one by one (cmlt: the same image bit for bit — its and "  \
         "pssmlt's path-traced direct pass and pilot trace in packets either way; pt: the "  \
         "scalar reference, the same estimator) (for timing comparisons)")                  \
    TOKEN(kernel, "auto", "auto general", "", "--kernel",                                   \
          "material kernels: auto (materials that are exact Lambertians on the frame take "  \
          "the diffuse-only kernel; the same image to float rounding, fewer instructions) "  \
          "or general (the full UsdPreviewSurface model everywhere, the reference)")         \
    TOKEN(mlt_path_sampler, "bdpt", "bdpt pt", "", "",                                       \
          "pssmlt's path sampler: bdpt (multiplexed over depth and strategy (s, t)) or pt "  \
          "(the path tracer)")                                                               \
    REAL(mlt_camera_technique, -1.0, -1.0, 0.9,  false, "cmlt:cameraTechnique",                \
         "--camera-technique Q",                                                             \
         "pssmlt/cmlt with the bdpt path sampler: probability of the camera technique, "     \
         "which evaluates every strategy a path tracer has (s <= 1) along one camera path "  \
         "(one-sample MIS with the multiplexed strategies: caps f* of paths only they "     \
         "sample, such as caustics seen in a mirror or through glass); 0 = the "            \
         "multiplexed strategies alone; negative (the default) = auto: 0.7 where a "        \
         "material can be near-specular and the chains render the caustic paths alone, "   \
         "else 0")                                                                          \
    INT(error_groups, 8, 0, 64, "cmlt:errorGroups", "--error-groups G",                      \
        "pssmlt/cmlt: independent chain groups of the error estimate (chain c in group c "   \
        "mod G; the film keeps G partial sums, G times its memory); 0 = no estimate, 1 and " \
        "2 are refused (a variance and its jackknife need 3)")                               \
    REAL(target_error, 0.0, 0.0, settings_limits::k_inf, false, "cmlt:targetError",          \
         "--target-error E",                                                                 \
         "stop when the render's own relMSE estimate falls below E and its one-sided "      \
         "95-percent upper bound below 1.5 E (error_target.h), or when --spp/--time run "   \
         "out first; 0 = off")                                                               \
    BOOL(keep_group_images, false, "", "--group-images",                                     \
         "pssmlt/cmlt: write the error groups' images (partial renders) beside the frame")   \
    TOKEN(sampler, "auto", "auto independent sobol sobol-blocks", "cmlt:sampler", "--sampler",   \
          "numbers of the pixel samples (pt, bdpt, the Metropolis integrators' direct pass "  \
          "and pilot): sobol (Owen-scrambled Sobol points, each dimension stratified over a " \
          "pixel's samples: sampling/sobol.h), sobol-blocks (a sequence of its own for each " \
          "block of 8 samples, so that the error estimate is unbiased), independent "         \
          "(Philox), or auto: sobol, but sobol-blocks with --target-error (whose estimate "   \
          "needs independent blocks); the chains' numbers are independent either way")      \
    TOKEN(pixel_filter, "gaussian", "box triangle gaussian mitchell blackman-harris",        \
          "cmlt:pixelFilter", "--pixel-filter",                                              \
          "pixel reconstruction filter (film/filter.h): gaussian (the default: pbrt-v4's, "  \
          "radius 1.5, sigma = radius/3), box (radius 0.5: the one-pixel box), triangle, "   \
          "mitchell (B = C = 1/3, negative lobes) or blackman-harris")                       \
    REAL(filter_radius, 0.0, 0.0, 3.5, false, "cmlt:filterRadius", "--filter-radius PIXELS", \
         "radius of the pixel filter in pixels, 0 = the filter's default (box 0.5, "          \
         "triangle 1, gaussian 1.5, mitchell 2, blackman-harris 1.5)")

// Settings of the sequence that the Python frame loop reads (DESIGN.md §4); the core
// has no field for them. Same columns.
#define CMLT_SEQUENCE_SETTINGS(INT, REAL, U64, BOOL, TOKEN)                                  \
    BOOL(carry_states, true, "cmlt:temporal:carryStates", "--independent-frames",            \
         "start each frame's chains where the previous frame's started, coupled: a start "   \
         "moves only where its target changed (and follows the camera)")                    \
    BOOL(smooth_normalization, true, "cmlt:temporal:smoothNormalization", "--no-smoothing",  \
         "smooth the MLT normalisation b over neighbouring frames while the lighting does "  \
         "not change")                                                                       \
    BOOL(seed_per_frame, false, "cmlt:temporal:seedPerFrame", "--seed-per-frame",            \
         "fold the frame number into the random streams (independent noise per frame, for "  \
         "comparison; more flicker); off keeps stored seeds")
// clang-format on

/// Settings of one frame: the fields of the table above, plus inputs that the temporal
/// driver hands over (not settings: no default, range or flag).
struct RenderSettings {
#define CMLT_DECLARE_INT(name, def, lo, hi, attr, flag, doc) int name = def;
#define CMLT_DECLARE_REAL(name, def, lo, hi, lo_open, attr, flag, doc) double name = def;
#define CMLT_DECLARE_U64(name, def, attr, flag, doc) uint64_t name = def;
#define CMLT_DECLARE_BOOL(name, def, attr, flag, doc) bool name = def;
#define CMLT_DECLARE_TOKEN(name, def, allowed, attr, flag, doc) std::string name = def;
    CMLT_RENDER_SETTINGS(CMLT_DECLARE_INT, CMLT_DECLARE_REAL, CMLT_DECLARE_U64, CMLT_DECLARE_BOOL,
                         CMLT_DECLARE_TOKEN)
#undef CMLT_DECLARE_INT
#undef CMLT_DECLARE_REAL
#undef CMLT_DECLARE_U64
#undef CMLT_DECLARE_BOOL
#undef CMLT_DECLARE_TOKEN

    /// pssmlt/cmlt: start the chains from these states instead of resampling the
    /// bootstrap (one chain per state; integrators/mlt/chain_state.h). nullptr / empty:
    /// bootstrap.
    std::shared_ptr<const mlt::ChainStates> mlt_initial_states;
    /// pssmlt/cmlt: f* of the frame's bootstrap samples 0..n-1 to use instead of
    /// evaluating them (the temporal driver evaluates them before the render, to choose
    /// the chain starts: temporal/carry.h). Exactly the frame's bootstrap count; counted
    /// in the budget as if evaluated. nullptr: the render evaluates them.
    std::shared_ptr<const std::vector<double>> mlt_bootstrap_f;
    /// The frame's film offset on the torus, [0, 1) per axis: the image's screen motion
    /// since the shot's first frame, which the temporal driver follows so that noise moves
    /// with the surfaces. The chains' film position is shifted by it (pssmlt_tracer.h
    /// shift_film) and the pixel passes' sample keys by it rounded to pixels
    /// (film/pass_splatter.h KeyShift: pt, bdpt, the Metropolis direct pass, the AOVs); both
    /// are bijections, so every pixel's estimator is unchanged. A key map (pixel_keys)
    /// replaces it for both. Default 0, 0.
    double film_offset_x = 0.0, film_offset_y = 0.0;
    /// The sample key of each image pixel (W·H, row-major; a permutation of 0..W·H−1):
    /// when given, it replaces the film offset for the pixel passes' keys (KeyShift) and
    /// for the chains' film position (pssmlt_tracer.h FilmMap: the film sample in key k's
    /// pixel cell lands in the pixel whose key is k), so each pixel's numbers and states
    /// follow its own screen motion (the temporal driver's key map: parallax, moving
    /// objects). Bijections like the shift: every estimator is unchanged. nullptr
    /// (default): the film offset.
    std::shared_ptr<const std::vector<uint32_t>> pixel_keys;
    /// The pilot image (H, W, 3) of the "pixel" importance to use instead of rendering one
    /// (the temporal driver renders it once per frame for the render and its carry-over
    /// evaluations). Its cost is counted as if rendered (pilot_spp · W·H evaluations).
    std::shared_ptr<const std::vector<float>> pilot;

    /// One part of a frame split over processes (cmlt.shot.distributed): with `partial`,
    /// pt renders only rows [part_row_begin, part_row_end) (the other rows stay 0);
    /// pssmlt/cmlt run only chains [part_chain_begin, part_chain_end) of the frame's
    /// chains and their direct pass only on those rows, and return the raw sums
    /// (RenderResult::partial) that combine_mlt_parts adds up exactly into the image
    /// of the whole frame. The parts' images are not the frame's. Not settings: the
    /// distributed frame loop sets them per task.
    bool partial = false;
    int part_row_begin = 0, part_row_end = 0;
    uint64_t part_chain_begin = 0, part_chain_end = 0;

    /// Every field against the table's range, and width · height <= 2^31. Throws
    /// SettingsError "RenderSettings.<field>: ..." naming the field.
    void validate() const;
};

/// RenderSettings::sampler as the pixel samplers' sequence (sampling/rng.h).
/// "auto" is one Sobol sequence per pixel except for a frame that stops at a target
/// error: its relMSE estimate needs the variance of the pixels' means, which the spread
/// of independent blocks gives (sobol-blocks) and the spread of one sequence's samples
/// over-estimates (by about the factor the points gain: README, "Pixel samples").
inline PixelSequence pixel_sequence(const RenderSettings& s) {
    if (s.sampler == "sobol" || (s.sampler == "auto" && !(s.target_error > 0.0))) return PixelSequence::sobol;
    if (s.sampler == "sobol-blocks" || s.sampler == "auto") return PixelSequence::sobol_blocks;
    return PixelSequence::independent;
}

/// The resolved sampler's name (RenderStats::sampler).
inline const char* pixel_sequence_name(PixelSequence seq) {
    switch (seq) {
        case PixelSequence::sobol: return "sobol";
        case PixelSequence::sobol_blocks: return "sobol-blocks";
        case PixelSequence::independent: break;
    }
    return "independent";
}

/// Statistics of a Metropolis render (pssmlt, cmlt).
struct MltStats {
    bool enabled = false;
    double b = 0, b_stderr = 0;                      ///< normalisation E[f*], bootstrap + large steps
    double b_bootstrap = 0, b_bootstrap_stderr = 0;  ///< from the bootstrap alone
    uint64_t bootstrap_samples = 0;                  ///< used (≤ the setting, ≤ half the budget)
    uint64_t bootstrap_nonzero = 0;                  ///< bootstrap samples with f* > 0
    uint64_t bootstrap_probe = 0;                    ///< samples of the auto size's probe (0: none ran)
    uint64_t bootstrap_probe_nonzero = 0;            ///< of them with f* > 0
    uint64_t chains = 0;
    uint64_t mutations = 0;                          ///< Markov-chain steps taken
    double mutations_per_pixel = 0;                  ///< mutations / (W·H)
    double large_step_probability = 0, sigma = 0;
    uint64_t small_steps = 0, large_steps = 0;
    double acceptance_small = 0, acceptance_large = 0;  ///< fraction of steps that moved
    uint64_t max_rejection_streak = 0;               ///< longest run of rejections in a chain
    uint64_t long_streak_rejections = 0;             ///< rejections in runs longer than 1000
    std::string path_sampler;                        ///< pssmlt: "bdpt" | "pt"
    uint64_t imported_chains = 0;                    ///< chains started from given states
    uint64_t clamped_splats = 0;                     ///< splats beyond the film's range
    uint64_t states_visited = 0;                     ///< distinct chain states (runs)
    double top_occupancy = 0;                        ///< share of steps spent in the most-
                                                     ///< occupied 0.1 % of the states
    double max_chain_share = 0;                      ///< largest share of the chains' splat
                                                     ///< luminance one chain contributed
    uint64_t stuck_chains = 0;                       ///< chains above 100x the fair share, or
                                                     ///< with >= 1000 rejections in a row
    double max_stay_share = 0;                       ///< heaviest stay of one chain on one state
    std::string importance;                          ///< "pixel" | "luminance"
    uint64_t pilot_evaluations = 0;                  ///< budget spent on the pilot image
    uint64_t direct_evaluations = 0;                 ///< budget spent on the direct pass
    bool direct_alone = false;                       ///< the direct pass rendered the frame
                                                     ///< (chainless, or no chain started)
    int min_depth = 0;                               ///< shortest path the chains render
    double camera_technique = 0;                     ///< q of the camera technique (resolved)
    std::string paths;                               ///< mlt_paths (resolved: all, caustics, none)
    double time_budget = 0;                          ///< seconds (0: none)
    std::string kernel_stats_json;                   ///< mlt::KernelStats::write_json (cmlt:
                                                     ///< + lens/caustic/pixel_move)
    // cmlt only
    int tries = 0, inner_length = 0;                 ///< k, m
    std::string inner;                               ///< inner rule
    bool packets = false;                            ///< bundles traced as packets
    int packet_width = 0;                            ///< widest packet used (1 = scalar)
    uint64_t packet_queries = 0;                     ///< packet calls (rtcIntersectN + rtcOccludedN)
    uint64_t packet_rays = 0;                        ///< rays answered by packets (active lanes)
    uint64_t packet_shadow_rays = 0;                 ///< of them, visibility rays (rtcOccludedN)
    uint64_t bundle_rays = 0;                        ///< rays of the points evaluated in lockstep (bundles, large steps)
    double bundle_busy_s = 0;                        ///< CPU time evaluating bundles
    double bundle_trace_s = 0;                       ///< of it, inside BVH queries
    uint64_t path_evaluations = 0;                   ///< paths traced, bootstrap included
};

struct RenderStats {
    double time_s = 0;
    uint64_t samples = 0;       ///< pixel samples taken
    uint64_t camera_rays = 0;
    uint64_t shadow_rays = 0;
    uint64_t rays = 0;          ///< every BVH query (camera + bounce + shadow)
    uint64_t packets = 0;       ///< pt: packet queries (rtcIntersectN + rtcOccludedN calls)
    uint64_t lane_hits = 0;     ///< pt: surface hits shaded in the diffuse lanes (diffuse_lanes.h)
    uint64_t splats = 0;        ///< bdpt: light-tracing (t = 1) contributions splatted
    /// Every integrator: lights under a pixel across traced from the light side to the
    /// lens ((1, 1): integrators/path/lens_light_tracing.h)
    uint32_t lens_lights = 0;
    /// pt: casters (instances that may be specular) its caustic light paths aim at, 0
    /// when it traces none (integrators/path/caustic_light_tracing.h)
    uint32_t caustic_casters = 0;
    /// bdpt, pssmlt, cmlt: share of the guided lights' subpaths aimed at the casters
    /// (RenderSettings::emission_guiding where it took effect, else 0;
    /// lights/emission_guide.h)
    double emission_guiding = 0;
    /// pssmlt, cmlt with auto guiding: the casters' coverage of the lights' directions
    /// it decided on (lights/emission_guide.h, caster_coverage), else −1
    double caster_coverage = -1;
    /// pssmlt, cmlt where the start probe ran (RenderSettings::mlt_min_starts,
    /// mlt::probe_starts): the bootstrap samples predicted to carry light for the chains,
    /// else −1; `mlt_too_few_starts`: below mlt_min_starts, the frame rendered without chains
    double mlt_expected_starts = -1;
    bool mlt_too_few_starts = false;
    std::string pixel_filter;   ///< the reconstruction filter used (film/filter.h)
    double filter_radius = 0;   ///< its radius in pixels (the default resolved)
    std::string sampler;        ///< the pixel samples' numbers: "sobol" | "sobol-blocks" | "independent" (resolved)
    /// pt, bdpt: the variance of a sum of many neighbouring pixels over the sum of their
    /// variance-AOV entries — 1 for independent pixels (the one-pixel box), the filter's
    /// PixelFilter::splat_correlation when camera samples are splatted to neighbours
    /// (film/pass_splatter.h). Block and image-mean standard errors multiply by its root.
    double pixel_correlation = 1;
    double rays_per_s = 0;
    /// CPU time summed over the worker threads: busy in the frame's parallel work, of it
    /// inside BVH queries (tracing), and the rest (shading: BSDFs, lights, sampling, MIS,
    /// splatting). Serial parts of the frame (setup, reductions) are in neither.
    double busy_s = 0, trace_s = 0, shade_s = 0;
    uint64_t nan_samples = 0;   ///< non-finite samples dropped by the film
    int first_nan_x = -1, first_nan_y = -1;
    int64_t first_nan_sample = -1;
    int threads = 0;
    std::string integrator;
    int spp = 0;
    uint64_t seed = 0;
    MltStats mlt;                  ///< filled by the Metropolis integrators, pssmlt and cmlt
                                   ///< (mlt.enabled)
};

/// pssmlt/cmlt with RenderSettings::partial: what a part of a frame adds to it.
struct MltPart {
    std::vector<uint64_t> splat_lo;  ///< SplatFilm words (W·H·3): the 128-bit sums' low
    std::vector<int64_t> splat_hi;   ///< and high words (film/splat_film.h)
    /// NormalisationAccumulator of the bootstrap, then of each chain of the part in chain
    /// order: (count, nonzero) pairs and (mean, m2) pairs.
    std::vector<uint64_t> norm_counts;
    std::vector<double> norm_moments;
    uint64_t steps = 0;  ///< kernel steps of the part's chains
};

struct RenderResult {
    int width = 0, height = 0;
    std::vector<float> image;     ///< (H, W, 3), row 0 at the top
    std::vector<float> variance;  ///< (H, W, 3), sample variance of the pixel mean
    /// (H, W, 3), the pixel's mean without its largest and smallest pass or block (Film::develop; the
    /// relMSE estimate's denominator, error_target.h); pssmlt/cmlt: the direct pass's
    std::vector<float> robust;
    /// pssmlt / cmlt with a direct pass: its image (H, W, 3), already part of `image`
    /// (the rest is the chains', which the temporal driver rescales); else empty.
    std::vector<float> direct;
    /// pssmlt / cmlt: f* of every bootstrap sample, by index (keyed by (seed, bootstrap,
    /// i): with stored seeds the same points every frame, so two frames' values pair up
    /// — the temporal driver's change detection). Empty for pt / bdpt.
    std::vector<float> bootstrap_f;
    bool cancelled = false;
    RenderStats stats;
    /// The render's own relMSE estimate (integrators/common/error_target.h) and its
    /// standard error; NaN where there is none (pssmlt/cmlt with error_groups 0).
    double error_estimate = std::numeric_limits<double>::quiet_NaN();
    double error_stderr = std::numeric_limits<double>::quiet_NaN();
    /// Why the frame ended: "budget" (spp), "time", "target" (target_error reached),
    /// "cancelled" (the progress callback).
    std::string stop_reason;
    /// With target_error > 0: the estimate after every chunk (pt, bdpt) or chain round
    /// (pssmlt, cmlt), as (work done: passes or path evaluations per pixel, seconds,
    /// estimate, its standard error).
    std::vector<std::array<double, 4>> error_history;
    /// pssmlt/cmlt with error_groups G >= 3: G images (G, H, W, 3), group g from the
    /// chains c with c mod G = g (each an unbiased image of the frame with the shared b
    /// and direct pass), and their path evaluations; else empty.
    std::vector<float> group_images;
    std::vector<double> group_weights;
    /// pssmlt / cmlt: the final state of every chain (integrators/mlt/chain_state.h).
    std::shared_ptr<mlt::ChainStates> mlt_states;
    /// pssmlt / cmlt: the state every chain started the frame from (after resampling or
    /// import).
    std::shared_ptr<mlt::ChainStates> mlt_start_states;
    /// pssmlt / cmlt with RenderSettings::partial: the part's raw sums; else null.
    std::shared_ptr<MltPart> mlt_part;
};

/// Called from the calling thread between chunks with (done, total) samples per pixel;
/// return false to stop after the current chunk.
using ProgressCallback = std::function<bool(uint64_t done, uint64_t total)>;

}  // namespace cmlt
