#pragma once
/// \file Bidirectional path tracing (Veach 1997 ch. 10; structure after pbrt-v4's BDPT).
///
/// Estimates pixel measurements with every connection strategy (s, t): s light-subpath
/// vertices, t camera-subpath vertices, path depth s + t - 2 scattering events
/// (`max_depth` as in the path tracer: 1 = direct lighting). Strategies:
///  * s = 0: the camera subpath hits an emitter (area / mesh / infinite lights);
///  * s = 1: the last camera vertex samples a light (as next-event estimation);
///  * t = 1: a light-subpath vertex connects to the camera and is splatted at its raster
///    position (light tracing), with the camera importance of CameraImportance: the
///    pinhole's We = 1 / (A cos^4) (A: image-plane area at distance 1), or, with a thin
///    lens (Camera::has_lens), a point sampled uniformly on the lens (connection
///    stream) and We = 1 / (A A_lens cos^4), the raster position being where the ray
///    from the lens point through the vertex meets the plane of focus;
///  * otherwise: connect the two subpath ends by a shadow ray.
/// (s, t) = (1, 1) -- a point on a light connected to the lens, the only strategy that
/// finds a light too small for camera rays to hit (a sub-millimetre bulb seen directly)
/// -- is on for the lights set_direct_light_tracing names (the bdpt integrator: the
/// lights under a pixel across, LensLightTracing::sub_pixel_lights; for a light camera
/// rays hit easily it would add a connection and a splat per sample for little; the
/// Metropolis integrators leave depth 0 to their direct pass or to (0, 2) alone) that
/// can give their radiance toward the lens (Light::le_toward: area, sphere, cylinder
/// and mesh lights; not point or infinite lights, which camera rays cannot hit or
/// which a point camera cannot connect to). For every other light, lights seen
/// directly come from (0, 2) with weight 1.
/// An orthographic camera cannot be connected to: t = 1 is disabled and the camera
/// vertex is treated as a Dirac vertex in the MIS weights, so the remaining strategies'
/// weights still sum to 1. A lens camera vertex is not Dirac: its lens-position density
/// is the same for t = 1 and t >= 2 and cancels in the ratio walk, which never moves
/// the connection past the camera vertex (there is no t = 0).
///
/// MIS: power heuristic over all strategies that can sample the path, computed with the
/// ratio walk over per-vertex forward / reverse area densities (pbrt-v4 MISWeight).
/// A connection through a Dirac vertex (specular lobe, point or delta-distant light for
/// s = 0) is impossible: its strategy gets weight 0 and contributes nothing. The camera
/// direction density is that of the whole image, 1 / (A cos^3), which with one light
/// path per pixel sample gives the right sample-count ratio between t = 1 and t >= 2.
///
/// Pass-through surfaces (opacityThreshold cut-outs, ior-1 interfaces with opacity < 1;
/// Scene::has_pass_through): a walk that samples the pass-through lobe crosses the
/// surface without making a vertex (throughput T / p, p the lobe's probability), and a
/// connection crosses it with weight T (Scene::transmittance), so both describe the
/// same paths. A segment's densities include the product of its crossings' p
/// (PathVertex::pass_pdf; the connection's from Scene::transmittance). A subpath end on
/// such a surface exists only with its walk's scattering probability 1 - p: connect
/// divides it out and mis_weight gives each strategy its ends' factor (interior vertices
/// need none: it cancels against the conditional density of the next direction).
/// Emissive materials are not pass-through surfaces (materials/material_eval.h).
///
/// Light subpaths carry importance: at each light-subpath vertex the adjoint BSDF gets
/// the shading-normal correction |wo.ns| |wi.ng| / (|wo.ng| |wi.ns|) (Veach 1997 §5.3).
///
/// Densities of a light's first vertex: choose the light by the scene's power pmf, then
/// its emission position (pmf * pdf_pos) -- the s = 1 strategy is weighted with that
/// density too (pbrt's convention), though it samples with sample_li: unbiased either
/// way, only the weights differ from the optimal. Infinite lights emit from a disk of
/// the scene's bounding radius, perpendicular to a direction from sample_li.
///
/// Emission guided to the casters (set_emission_guiding; lights/emission_guide.h): with
/// probability g (RenderSettings::emission_guiding: auto 0.5 for the bdpt integrator, and
/// for the chains of pssmlt and cmlt where the casters are rarely reached without it,
/// mlt_context.h; no effect where no instance may be specular) a finite light's subpath leaves its point toward a mirror or glass object
/// instead of along the light's own emission sampling, so the light-tracing strategies
/// find caustic paths (L S+ D … E) that emission toward the whole hemisphere rarely
/// starts. The direction density is the mixture (1 − g) p_light(ω) + g p_guide(ω) in
/// sampling and in the MIS weights alike (pdf_light). Guided: finite lights that are not
/// Dirac and give le_toward (area, sphere, disk, cylinder, mesh lights). The random
/// numbers are the same five as without (light, position, direction): the direction's
/// first number picks the branch and, rescaled, the caster, so the Metropolis
/// integrators' primary-sample layout does not change.
///
/// Motion blur (Scene::motion_blur()): each sample has one shutter time, drawn from the
/// camera stream, that every ray of both subpaths and of the connections carries
/// (PathVertex::time), as PT gives every ray of a path its camera ray's time.
///
/// Random numbers: stream 0 (camera): film position (2D), shutter time (1D, only with
/// motion blur), lens position (2D, only with a thin lens), then per camera vertex BSDF
/// direction (2D), lobe, roulette. Stream 1 (light): light choice, emission position
/// (2D), emission direction (2D), then per vertex as the camera. Stream 2
/// (connections): per s = 1 strategy, light choice and position (2D); per t = 1
/// strategy with a thin lens, the lens position (2D).
#include "cameras/camera.h"
#include "integrators/bdpt/camera_importance.h"
#include "integrators/bdpt/path_sampler.h"
#include "integrators/bdpt/path_vertex.h"
#include "integrators/common/path_counters.h"
#include "integrators/common/path_partition.h"
#include "lights/emission_guide.h"

#include <cstdint>
#include <vector>

namespace cmlt {

class Scene;
struct SceneHit;

/// The rays and samples of PathCounters, and the light-tracing splats.
struct BdptCounters : PathCounters {
    uint64_t splats = 0;
    uint64_t bad_splats = 0;  ///< non-finite t = 1 contributions (dropped)
};

/// A light-tracing contribution (t = 1) at a raster position. Summed over one light path
/// per pixel, it is that pass's estimate of the t = 1 part of each pixel.
struct BdptSplat {
    Vec2 p_raster;
    Spectrum L;
};

/// A subpath's random walk between two ray queries: everything BdptTracer's walk step
/// needs to consume the hit of `ray` and produce the next ray. The scalar walk
/// (generate_camera_subpath, generate_light_subpath) is a loop over that step; coherent
/// MLT keeps one walk per candidate of a bundle and traces the candidates' rays
/// together (BdptStrategyLane), so both run the same arithmetic.
struct BdptWalk {
    Ray ray;                 ///< the ray whose hit the next step consumes
    Spectrum beta{0.f};      ///< throughput
    Spectrum rr_beta{1.f};   ///< scattering throughput alone (roulette without light units)
    float pdf_fwd_sa = 0.f;  ///< solid-angle density of `ray`'s direction
    /// Product of the pass-through crossings' probabilities since path[n - 1].
    float pass_pdf = 1.f;
    PathVertex* path = nullptr;
    int n = 0;               ///< vertices made so far (path[n - 1] is the last)
    int start = 0, max_vertices = 0;
    bool importance = false, roulette = false;
};

/// A connection (BdptTracer::connect) split at its visibility query: the unoccluded
/// contribution and the shadow ray, finished once the ray's transmittance is known.
struct BdptConnection {
    const PathVertex* light = nullptr;
    const PathVertex* camera = nullptr;
    int s = 0, t = 0;
    bool mis = true;
    bool tail = false;       ///< reached the MIS tail (sets connect's `sampled` output)
    Spectrum L{0.f};         ///< contribution without the visibility
    Spectrum result{0.f};    ///< the finished contribution
    PathVertex sampled;      ///< the new endpoint of s = 1 / t = 1
    Vec2 p_raster;           ///< t = 1: raster position of the connection
    Ray shadow;              ///< the visibility query (Scene::transmittance semantics)
};

/// Per-thread scratch of BdptTracer::li: the two subpaths, the t = 1 splats, and the
/// sample's connections with their shadow rays (answered together).
struct BdptWorkspace {
    std::vector<PathVertex> camera, light;
    std::vector<BdptSplat> splats;
    std::vector<BdptConnection> conns;
    std::vector<uint8_t> pending;    ///< per connection: its shadow ray is still to be answered
    std::vector<Ray> rays;           ///< per connection: its shadow ray
    std::vector<uint32_t> queries;   ///< connections whose rays go to the BVH
    std::vector<uint8_t> occluded;   ///< per connection: the BVH's answer
};

/// The query a resumable BDPT evaluation (BdptStrategyLane) waits for.
enum class BdptQuery : uint8_t {
    none,        ///< finished: the lane's `result` and `p_raster` are set
    intersect,   ///< Scene::intersect of `walk.ray`, then BdptTracer::resume_strategy(hit)
    visibility,  ///< Scene::transmittance of `conn.shadow`, then resume_strategy(tr, pass_pdf)
};

/// BdptTracer::evaluate_strategy as a resumable computation: begin_strategy runs it to
/// its first ray query, each resume_strategy consumes one answer and runs to the next.
/// The numbers come from `sampler` in the same order as evaluate_strategy reads them
/// (camera stream, then light, then connection), and every step is the scalar code's,
/// so the result is evaluate_strategy's for the same answers.
struct BdptStrategyLane {
    enum class Stage : uint8_t { camera_walk, light_walk, connection, done };
    int depth = 0, s = 0, t = 0;
    bool mis = true;  ///< MIS-weighted (false: the unweighted strategy, for tests)
    BdptSampler* sampler = nullptr;
    BdptWorkspace* ws = nullptr;
    Stage stage = Stage::done;
    BdptWalk walk;
    BdptConnection conn;
    float light_disk_pdf = 0.f;
    Vec2 p_raster;           ///< film position, or the light-tracing splat's (t = 1)
    Spectrum result{0.f};    ///< MIS-weighted contribution (when finished)
    BdptCounters counters;   ///< this evaluation's rays

    /// The ray of a pending query.
    const Ray& query_ray(BdptQuery q) const { return q == BdptQuery::intersect ? walk.ray : conn.shadow; }
};

class BdptTracer {
public:
    static constexpr int k_rr_start_depth = 3;

    /// `film_margin`: the film window reaches that many pixels beyond the image on every
    /// side (PixelFilter::margin): light tracing splats there, and evaluate_strategy's
    /// film positions cover it.
    BdptTracer(const Scene& scene, const Camera& camera, int width, int height, int max_depth,
               float film_margin = 0.f);

    /// All strategies for one pixel sample at raster position `p_raster` (the caller
    /// picks it; the camera stream's first 2D is *not* consumed here). Returns the
    /// estimate of the strategies with t >= 2; t = 1 contributions are appended to
    /// `ws.splats` (the caller clears it).
    Spectrum li(const Vec2& p_raster, BdptSampler& sampler, BdptWorkspace& ws,
                BdptCounters& c) const;

    /// One strategy (s, t) of a path with `depth` scattering events (s + t = depth + 2),
    /// for the Metropolis integrators: the camera stream's first 2D is the film position
    /// over the whole film window (the image and its margin), subpaths have exactly t and s vertices (no Russian
    /// roulette). Returns the MIS-weighted contribution and its raster position:
    /// E[ evaluate_strategy / strategy_pmf * h(p_raster) ] = ∫ h I / A for the window's
    /// area A ((W + 2 margin)(H + 2 margin) pixels; W H without a margin).
    /// It is the resumable strategy below with Scene::intersect and
    /// Scene::transmittance answering its queries inline (tested bit for bit).
    Spectrum evaluate_strategy(int depth, int s, int t, BdptSampler& sampler, BdptWorkspace& ws,
                               Vec2* p_raster, BdptCounters& c, bool mis = true) const;
    /// The Metropolis integrators' camera technique (mlt/technique.h): every strategy
    /// with s ≤ 1 and t ≥ 2 along one camera subpath (Russian roulette on, up to
    /// max_depth), strategy (s, t) of depth d weighted by weights[2 d + s] (0: left
    /// out). The camera stream's first 2D is the film position over the film window
    /// (as evaluate_strategy; *p_raster); the light stream gives the light vertex of
    /// s = 1's MIS densities, the connection stream each s = 1 connection's light sample
    /// in the order of t. Returns Σ weight · MIS-weighted C_st (all at *p_raster).
    Spectrum evaluate_camera_strategies(const std::vector<float>& weights, BdptSampler& sampler,
                                        BdptWorkspace& ws, Vec2* p_raster, BdptCounters& c) const;
    /// Resumable evaluate_strategy (BdptStrategyLane: coherent MLT answers its ray
    /// queries, the camera ray first). Returns the first query, or none when done.
    BdptQuery begin_strategy(BdptStrategyLane& lane, int depth, int s, int t, BdptSampler& sampler,
                             BdptWorkspace& ws, bool mis = true) const;
    /// Consume the answer to an intersect query (Scene::intersect's for lane.walk.ray).
    BdptQuery resume_strategy(BdptStrategyLane& lane, const SceneHit& hit) const;
    /// Consume the answer to a visibility query: Scene::transmittance(lane.conn.shadow).
    BdptQuery resume_strategy(BdptStrategyLane& lane, float transmittance, float pass_pdf) const;

    /// Number of strategies for a depth (depth + 2, except depth 0: only (0, 2)).
    static int strategy_count(int depth) { return depth == 0 ? 1 : depth + 2; }
    /// Pick (s, t) uniformly for `depth` with u in [0, 1); returns its probability.
    static float choose_strategy(int depth, float u, int* s, int* t);

    /// Unweighted contribution of (s, t) (MIS weight 1), for the per-strategy tests.
    Spectrum evaluate_strategy_unweighted(int depth, int s, int t, BdptSampler& sampler,
                                          BdptWorkspace& ws, Vec2* p_raster,
                                          BdptCounters& c) const;

    /// Debug: for the path made by connecting light[0..s) and camera[0..t) (+ the
    /// `sampled` endpoint for s = 1 or t = 1), the MIS weight of every strategy
    /// s' = 0..s+t-1 (weights[s']), computed by the production weight function on
    /// subpaths rebuilt from the path's geometry; impossible strategies get 0. Also
    /// returns (weight_here) the weight computed from the subpaths as sampled.
    std::vector<float> strategy_weights(const PathVertex* light, int s, const PathVertex* camera,
                                        int t, const PathVertex& sampled,
                                        float* weight_here) const;

    /// Subpath generation (exposed for tests): number of vertices made.
    int generate_camera_subpath(const Vec2& p_raster, BdptSampler& sampler, int max_vertices,
                                bool roulette, PathVertex* path, BdptCounters& c) const;
    /// `time`: the sample's shutter time (the camera subpath's, camera[0].time).
    int generate_light_subpath(BdptSampler& sampler, int max_vertices, bool roulette,
                               PathVertex* path, BdptCounters& c, float time = 0.f) const;
    /// Connect; unweighted if `mis` is false. For t = 1 sets *p_raster; `sampled` gets
    /// the new endpoint for s = 1 / t = 1.
    Spectrum connect(const PathVertex* light, int s, const PathVertex* camera, int t,
                     BdptSampler& sampler, Vec2* p_raster, bool mis, BdptCounters& c,
                     PathVertex* sampled = nullptr) const;

    int max_depth() const { return m_max_depth; }
    /// li's shadow rays: a sample's connections ask theirs together, in Embree packets
    /// of up to `width` rays (Accel::occluded_lanes); 1 (the default): one at a time.
    /// The same numbers in the same order either way; the image can differ only where
    /// Embree's packet and single-ray kernels answer a ray differently.
    void set_packet_width(int width) { m_packet_width = width; }
    /// Evaluate only the paths of one class (integrators/common/path_partition.h): every
    /// strategy gives a path of the other class 0 (before its shadow ray). The
    /// Metropolis integrators' chains with mlt_paths = "caustics". Null or
    /// PathPart::all (the default): every path.
    void set_partition(const PathPartition* partition) {
        m_partition = PathPartition::restricting(partition);
    }
    /// Is the path of strategy (s, t) on these subpaths a caustic path (path_partition.h)?
    /// Needs a partition (its material table).
    bool caustic_path(const PathVertex* light, int s, const PathVertex* camera, int t) const;
    /// Turn the (1, 1) strategy on for these lights (indices into Scene::light; li and
    /// the MIS weights of paths of depth 0); none by default (file comment).
    void set_direct_light_tracing(const std::vector<uint32_t>& lights);
    /// Guide light subpaths' emission to the casters with probability `fraction` (file
    /// comment); 0 (the default) or a scene without casters: the light's own sampling.
    void set_emission_guiding(float fraction);
    /// The guided fraction in effect (0 without casters or guided lights).
    float emission_guiding() const { return m_guided_lights ? m_guide_fraction : 0.f; }
    /// Whether (1, 1) is a strategy for the depth-0 path ending at `x0`: its light is
    /// on, the camera one can connect to, and the light finite, not Dirac and giving
    /// le_toward.
    bool direct_light_tracing(const PathVertex& x0) const;
    /// The scene has motion blur (Scene::motion_blur() at construction): each sample
    /// draws a shutter time (see the random-number layout in the file comment).
    bool motion_blur() const { return m_motion_blur; }

private:
    // Random walks (BdptWalk): begin_walk sets one up and says whether it has a ray to
    // trace; walk_step consumes that ray's hit and says whether there is a next one;
    // run_walk is the scalar loop.
    bool begin_walk(BdptWalk& walk, const Ray& ray, const Spectrum& beta, float pdf_dir,
                    int max_vertices, bool importance, bool roulette, PathVertex* path,
                    int start) const;
    bool walk_step(BdptWalk& walk, const SceneHit& hit, BdptSampler& sampler, BdptCounters& c) const;
    void run_walk(BdptWalk& walk, BdptSampler& sampler, BdptCounters& c) const;
    /// generate_camera_subpath up to its walk: the camera vertex, and the walk if one is
    /// needed (returns true; walk.n is the vertex count either way).
    bool begin_camera_subpath(const Vec2& p_raster, BdptSampler& sampler, int max_vertices,
                              bool roulette, PathVertex* path, BdptCounters& c,
                              BdptWalk& walk) const;
    /// generate_light_subpath up to its walk (as begin_camera_subpath); `disk_pdf` for
    /// end_light_subpath.
    bool begin_light_subpath(BdptSampler& sampler, int max_vertices, bool roulette, PathVertex* path,
                             float time, BdptWalk& walk, float* disk_pdf) const;
    /// The light subpath's first surface density, from positions, once its walk is done.
    void end_light_subpath(PathVertex* path, int n, float disk_pdf) const;
    /// connect up to the visibility query: true if `conn.shadow` must be answered by
    /// finish_connect, false if the connection is finished (conn.result).
    bool begin_connect(const PathVertex* light, int s, const PathVertex* camera, int t,
                       BdptSampler& sampler, bool mis, BdptCounters& c, BdptConnection& conn) const;
    /// The rest of connect given Scene::transmittance's answer for conn.shadow; sets
    /// *p_raster for t = 1.
    Spectrum finish_connect(BdptConnection& conn, float tr, float pass_pdf, Vec2* p_raster) const;
    /// The end of connect shared by every strategy: the pass-through scattering
    /// probabilities of the subpath ends and the MIS weight.
    Spectrum connect_tail(BdptConnection& conn, float conn_pass_pdf) const;
    /// What evaluate_strategy and begin_strategy start with: false if (s, t) is no
    /// strategy of `depth`; else the workspace sized, the sample counted, the film position
    /// (the camera stream's first 2D) in *p_raster.
    bool start_strategy(int depth, int s, int t, BdptSampler& sampler, BdptWorkspace& ws, Vec2* p_raster,
                        BdptCounters& c) const;
    /// Stages of the resumable strategy (BdptStrategyLane) after a walk ends.
    BdptQuery strategy_after_camera(BdptStrategyLane& lane) const;
    BdptQuery strategy_after_light(BdptStrategyLane& lane) const;
    BdptQuery strategy_connect(BdptStrategyLane& lane) const;
    /// MIS weight of strategy (s, t); `conn_pass_pdf`: the pass-through crossings of the
    /// connection segment (Scene::transmittance; 1 for s = 0); `pt_override` replaces
    /// camera[t - 1] (s = 0 on an escaped vertex: one infinite light at a time).
    float mis_weight(const PathVertex* light, int s, const PathVertex* camera, int t,
                     const PathVertex& sampled, float conn_pass_pdf = 1.f,
                     const PathVertex* pt_override = nullptr) const;
    // Densities (area measure unless `to` is an infinite light). convert_density,
    // is_delta_light and connectible are inline (bdpt_detail.h: every unit calls them per
    // vertex).
    inline float convert_density(float pdf_sa, const PathVertex& from, const PathVertex& to) const;
    float pdf(const PathVertex* prev, const PathVertex& v, const PathVertex& next) const;
    /// pdf(&a, v, b) in *ab and pdf(&b, v, a) in *ba, the same floats, the directions and
    /// the BSDF's shared terms computed once (mis_weight asks for both at each connection
    /// vertex).
    void pdf_pair(const PathVertex& a, const PathVertex& v, const PathVertex& b, float* ab, float* ba) const;
    float pdf_light(const PathVertex& v, const PathVertex& next) const;
    float pdf_light_origin(const PathVertex& v, const PathVertex& next) const;
    /// Solid-angle density of light `li` (finite) emitting from `p` along unit `w`, the
    /// light's own density being `own` (Light::pdf_le's pdf_dir): the guided mixture.
    float emission_pdf_dir(int32_t li, const Vec3& p, const Vec3& w, float own) const {
        if (!m_guided_lights || li < 0 || size_t(li) >= m_guided.size() || !m_guided[size_t(li)]) return own;
        return (1.f - m_guide_fraction) * own + m_guide_fraction * m_guide.pdf(p, w);
    }
    inline bool is_delta_light(const PathVertex& v) const;
    /// Probability that a walk arriving at v from neighbour `toward` scatters there
    /// (makes a vertex) instead of crossing a pass-through surface: 1 - the pass-through
    /// lobe's probability; 1 for vertices that cannot pass rays.
    float scatter_probability(const PathVertex& v, const PathVertex& toward) const;
    inline bool connectible(const PathVertex& v) const;
    /// BSDF value times the cosine at v toward direction w (unit), for radiance
    /// (camera-subpath) or importance (light-subpath, with the shading-normal correction).
    Spectrum scatter(const PathVertex& v, const Vec3& w, bool importance) const;
    /// The shadow ray of a connection a - b (offset ends, the sample's time).
    Ray connection_ray(const PathVertex& a, const PathVertex& b) const;

    const Scene& m_scene;
    CameraImportance m_importance;
    int m_width, m_height;
    float m_margin;
    int m_max_depth;
    bool m_motion_blur;
    std::vector<uint8_t> m_direct_light;  ///< per light: (1, 1) on; empty: on for none
    EmissionGuide m_guide;                ///< the casters (set_emission_guiding)
    std::vector<uint8_t> m_guided;        ///< per light: its emission guided
    bool m_guided_lights = false;         ///< some light guided, fraction > 0
    float m_guide_fraction = 0.f;
    int m_packet_width = 1;
    const PathPartition* m_partition = nullptr;
};

}  // namespace cmlt
