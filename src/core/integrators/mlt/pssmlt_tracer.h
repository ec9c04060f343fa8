#pragma once
/// \file The path function of primary-sample-space MLT, shared by both Metropolis
/// integrators (pssmlt's MltSampler chains, cmlt's keyed states and bundles) and the
/// temporal carry-over: turn a sampler's primary samples into a path sample (film
/// position, contribution, f*).
///
/// Two path samplers (RenderSettings::mlt_path_sampler):
///  * "bdpt" (default; multiplexed MLT, Hachisuka et al. 2014, DESIGN.md §2): the
///    technique — depth and strategy (s, t) — comes from the connection stream's
///    dimension 0 (technique.h), the path from BdptTracer::evaluate_strategy on the three
///    streams (camera stream dimension 0 = film position, then BDPT's layout; light
///    stream; connection stream from dimension 1). L = C_st / p(technique), f* =
///    luminance(L) = luminance(f · w_st / p_st) in the notation of DESIGN.md §2. The
///    integrator holds the technique samples fixed in small steps
///    (MltSampler::freeze_in_small_steps).
///  * "pt": camera stream only: dimension 0 = film position, then the path tracer's own
///    layout (path_tracer.h: bounce b uses 1 + 5b ..); L = PathTracer::li (NEE + MIS).
/// Both satisfy E[L · h(p_film)] = ∫ h I / (W·H) for a uniform state, so the
/// integrator's normalisation is the same.
///
/// Pixel filter (set_filter, film/filter.h): the film position covers the film window,
/// the image grown by the filter's margin (so that every pixel's footprint is sampled),
/// and L is scaled by window / image area to keep the relation above; the chains splat
/// L over the filter's footprint around p_film (splat_filtered). The unit box (the
/// default) has no margin: the film position and L are those without a filter.
#include "cameras/camera.h"
#include "film/filter.h"
#include "integrators/bdpt/bdpt_tracer.h"
#include "integrators/mlt/mlt_sampler.h"
#include "integrators/mlt/pixel_importance.h"
#include "integrators/mlt/technique.h"
#include "integrators/path/path_tracer.h"
#include "math/safe_math.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace cmlt::mlt {

/// One evaluated state of a chain: where it splats and what.
struct PathSample {
    uint32_t pixel = 0;  ///< y·W + x (the pixel containing p_film, clamped into the image)
    Vec2 p_film{0.f, 0.f};  ///< film position (raster), where its filtered splat centres
    Spectrum L{0.f};     ///< contribution (PT estimate for the sampled film position)
    double f = 0.0;      ///< f* = luminance(L) / P(pixel) (pixel_importance.h), ≥ 0
    bool invalid = false;  ///< L was not finite (f = 0, never splatted)
    int depth = -1, s = -1, t = -1;  ///< technique (bdpt sampler); -1 for the pt sampler
};

/// The film position of primary samples u ∈ [0,1)^2 shifted by `offset` on the torus
/// (RenderSettings::film_offset_x/y): a measure-preserving bijection of the film
/// square, so the chains' target and every estimator stay what they are; the temporal
/// driver moves it with the image's mean screen motion, so that chains replayed with the
/// same numbers follow the surfaces under a moving camera (temporal/carry.h).
inline Vec2 shift_film(const Vec2& u, const Vec2& offset) {
    const auto wrap = [](float v) { return clamp_below_one(v - std::floor(v)); };
    return offset.x == 0.f && offset.y == 0.f ? u : Vec2(wrap(u.x + offset.x), wrap(u.y + offset.y));
}

/// Where the chains' film sample u ∈ [0,1)² lands (RenderSettings::film_offset_x/y and
/// pixel_keys): the film offset's torus shift (shift_film), or with a key map a
/// permutation of the image's pixel cells — u in the cell of image pixel k (the film
/// window [-margin, W + margin) x [-margin, H + margin) mapped to u's square, as the
/// tracers map it) moves to the pixel whose key is k, its position within the pixel
/// kept; the margin's ring stays. Both keep the film square's measure, so the chains'
/// target and every estimator stay what they are; a chain replayed with the same
/// numbers follows its own pixel's screen motion, as the pixel passes' samples do
/// (film/pass_splatter.h KeyShift).
struct FilmMap {
    Vec2 offset{0.f, 0.f};
    const uint32_t* pixel_of_key = nullptr;  ///< the inverse of the key map (W·H), or nullptr
    int width = 0, height = 0;
    float margin = 0.f;

    Vec2 operator()(const Vec2& u) const {
        if (!pixel_of_key) return shift_film(u, offset);
        const float sx = float(width) + 2.f * margin, sy = float(height) + 2.f * margin;
        const float px = u.x * sx - margin, py = u.y * sy - margin;
        if (!(px >= 0.f && py >= 0.f && px < float(width) && py < float(height))) return u;
        const int cx = std::min(int(px), width - 1), cy = std::min(int(py), height - 1);
        const uint32_t p = pixel_of_key[size_t(cy) * size_t(width) + size_t(cx)];
        const float qx = float(p % uint32_t(width)) + (px - float(cx));
        const float qy = float(p / uint32_t(width)) + (py - float(cy));
        return Vec2(clamp_below_one((qx + margin) / sx), clamp_below_one((qy + margin) / sy));
    }
};

/// BdptSampler over a StreamSampler (base/sampler.h): BDPT's connection stream starts
/// after the technique dimensions; the camera stream's first 2-D sample (the film
/// position) goes through the film map.
template <class Sampler>
class BdptStreamAdapter final : public BdptSampler {
    static_assert(is_stream_sampler_v<Sampler>, "BdptStreamAdapter wraps a StreamSampler (base/sampler.h)");

public:
    explicit BdptStreamAdapter(Sampler& s, const FilmMap& film_map = FilmMap()) : m_s(s), m_map(film_map) {}
    void start_stream(int index) override {
        m_s.start_stream(uint32_t(index));
        m_film = index == BdptSampler::k_camera;
        if (index == BdptSampler::k_connection) m_s.set_dimension(k_technique_dimensions);
    }
    float next1d() override {
        m_film = false;
        return m_s.get1d();
    }
    Vec2 next2d() override {
        const bool film = m_film;
        m_film = false;
        return film ? m_map(m_s.get2d()) : m_s.get2d();
    }

private:
    Sampler& m_s;
    FilmMap m_map;
    bool m_film = false;
};

class PssmltTracer {
public:
    /// The "pt" path sampler.
    PssmltTracer(const PathTracer& tracer, const Camera& camera, int width, int height)
        : m_tracer(&tracer), m_camera(camera), m_width(width), m_height(height), m_technique(0) {}
    /// The "bdpt" path sampler (multiplexed over depth ∈ [0, bdpt.max_depth()] and (s, t),
    /// and the camera technique with probability `camera`: technique.h).
    /// Depths below `min_depth` are left out (a direct pass renders them).
    PssmltTracer(const BdptTracer& bdpt, const Camera& camera, int width, int height, int min_depth = 0,
                 double camera_technique = 0.0)
        : m_bdpt(&bdpt), m_camera(camera), m_width(width), m_height(height),
          m_technique(bdpt.max_depth(), min_depth, camera_technique) {}

    /// The pixel filter (outliving the tracer); nullptr: the unit box.
    void set_filter(const PixelFilter* filter) {
        m_filter = filter;
        m_margin = filter ? filter->margin() : 0.f;
        m_area_scale = filter ? filter->window_area(m_width, m_height) / (double(m_width) * double(m_height)) : 1.0;
    }
    const PixelFilter& filter() const {
        static const PixelFilter unit_box;
        return m_filter ? *m_filter : unit_box;
    }

    /// Where the camera stream's film position lands (FilmMap); default: unmoved.
    void set_film_map(const FilmMap& map) { m_film_map = map; }
    const FilmMap& film_map() const { return m_film_map; }

    /// The importance function of f* (pixel_importance.h); default: luminance.
    void set_importance(const PixelImportance* importance) { m_importance = importance; }
    const PixelImportance* importance() const { return m_importance; }

    bool bdpt() const { return m_bdpt != nullptr; }
    const TechniqueSampler& technique() const { return m_technique; }

    /// The camera ray of the sampler's current proposal (camera stream, dimension 0 =
    /// film position) and its pixel. With the bdpt sampler and motion blur the ray
    /// carries the sample's shutter time, BDPT's camera-stream dimension 1, so that a
    /// first hit traced from this ray is the one BdptTracer's camera ray would find.
    /// (The pt sampler keeps time 0.) Leaves the sampler on the camera stream after the
    /// numbers read here, where evaluate's path sampling continues.
    template <class Sampler>
    Ray camera_ray(Sampler& sampler, uint32_t* pixel, Vec2* p_film = nullptr) const {
        static_assert(is_stream_sampler_v<Sampler>, "a StreamSampler (base/sampler.h)");
        sampler.start_stream(MltSampler::camera);
        sampler.set_dimension(0);
        const Vec2 u = m_film_map(sampler.get2d());
        const Vec2 p_raster(u.x * (float(m_width) + 2.f * m_margin) - m_margin,
                            u.y * (float(m_height) + 2.f * m_margin) - m_margin);
        *pixel = pixel_of(p_raster);
        if (p_film) *p_film = p_raster;
        Ray ray = m_camera.generate_ray(p_raster);
        if (m_bdpt && m_bdpt->motion_blur()) ray.time = sampler.get1d();
        return ray;
    }

    /// Evaluate the sampler's current proposal. `Sampler`: a StreamSampler
    /// (base/sampler.h): MltSampler, coherent::PointSampler. `first_hit`, if given, is what
    /// camera_ray(sampler) hits first (coherent MLT traces the camera rays of a bundle
    /// as one Embree packet, integrators/cmlt): the camera ray is then not traced again.
    /// The pt sampler only: the bdpt sampler's bundles are evaluated by
    /// coherent::BundleEvaluator, which answers every ray query itself.
    template <class Sampler>
    PathSample evaluate(Sampler& sampler, PathCounters& counters,
                        const SceneHit* first_hit = nullptr) const {
        if (m_bdpt) return evaluate_bdpt(sampler, counters);
        PathSample s;
        const Ray ray = camera_ray(sampler, &s.pixel, &s.p_film);
        s.L = m_tracer->li(ray, sampler, counters, first_hit);
        if (m_area_scale != 1.0) s.L *= float(m_area_scale);
        if (!is_finite(s.L)) {
            s.invalid = true;
            s.L = Spectrum(0.f);
            return s;
        }
        s.f = target(s.L, s.pixel);
        return s;
    }

    /// f* of a contribution L landing in `pixel`.
    double target(const Spectrum& L, uint32_t pixel) const {
        const double y = target_luminance(L);
        return (m_importance && y > 0.0) ? y * m_importance->weight(pixel) : y;
    }

    int width() const { return m_width; }
    int height() const { return m_height; }
    const BdptTracer* bdpt_tracer() const { return m_bdpt; }

    /// Read the technique (depth, s, t) of the sampler's current proposal from the
    /// connection stream's dimension 0 (technique.h) into `s`; returns its probability
    /// (p_eff; 1 for the camera technique, whose depth, s and t are −1). The bdpt
    /// sampler only.
    template <class Sampler>
    double choose_technique(Sampler& sampler, PathSample& s) const {
        sampler.start_stream(MltSampler::connection);
        sampler.set_dimension(0);
        const Vec2 ut = sampler.get2d();
        return m_technique.choose(ut.x, ut.y, &s.depth, &s.s, &s.t);
    }

    /// The technique chosen into `s` (choose_technique) evaluated with `adapter`, its
    /// queries answered inline: the strategy's C, or the camera technique's weighted sum.
    Spectrum evaluate_technique(const PathSample& s, BdptSampler& adapter, BdptWorkspace& ws, Vec2* p_raster,
                                BdptCounters& c) const {
        if (s.depth < 0)
            return m_bdpt->evaluate_camera_strategies(m_technique.camera_weights(), adapter, ws, p_raster, c);
        return m_bdpt->evaluate_strategy(s.depth, s.s, s.t, adapter, ws, p_raster, c);
    }

    /// Pixel, L = C / p(technique) and f* of an evaluated strategy C at p_raster (the
    /// bdpt sampler; also the end of coherent MLT's resumable lanes, bundle_tracer.h).
    void finish_sample(PathSample& s, double pmf, const Spectrum& C, const Vec2& p_raster,
                       const BdptCounters& c, PathCounters& counters) const {
        counters += c;
        if (!is_finite(C)) {
            s.invalid = true;
            return;
        }
        // film position: the camera stream's (t ≥ 2) or the light-tracing splat's (t = 1)
        if (!(p_raster.x >= -m_margin && p_raster.y >= -m_margin && p_raster.x < float(m_width) + m_margin &&
              p_raster.y < float(m_height) + m_margin))
            return;  // off the film window: contributes nothing (f* = 0)
        s.pixel = pixel_of(p_raster);
        s.p_film = p_raster;
        s.L = C * float(m_area_scale / pmf);
        if (!is_finite(s.L)) {
            s.invalid = true;
            s.L = Spectrum(0.f);
            return;
        }
        s.f = target(s.L, s.pixel);
    }

private:
    template <class Sampler>
    PathSample evaluate_bdpt(Sampler& sampler, PathCounters& counters) const {
        PathSample s;
        const double pmf = choose_technique(sampler, s);
        thread_local BdptWorkspace ws;
        BdptCounters c;
        BdptStreamAdapter<Sampler> adapter(sampler, m_film_map);
        Vec2 p_raster;
        const Spectrum C = evaluate_technique(s, adapter, ws, &p_raster, c);
        finish_sample(s, pmf, C, p_raster, c, counters);
        return s;
    }

    /// The pixel containing raster position p, clamped into the image.
    uint32_t pixel_of(const Vec2& p) const {
        const int x = std::max(0, std::min(int(std::floor(p.x)), m_width - 1));
        const int y = std::max(0, std::min(int(std::floor(p.y)), m_height - 1));
        return uint32_t(y) * uint32_t(m_width) + uint32_t(x);
    }

    const PathTracer* m_tracer = nullptr;
    const PixelFilter* m_filter = nullptr;
    float m_margin = 0.f;        ///< the filter's (film window beyond the image)
    double m_area_scale = 1.0;   ///< window / image area
    const PixelImportance* m_importance = nullptr;
    const BdptTracer* m_bdpt = nullptr;
    const Camera& m_camera;
    int m_width, m_height;
    TechniqueSampler m_technique;
    FilmMap m_film_map;
};

}  // namespace cmlt::mlt
