#pragma once
/// \file Coherent MLT (DESIGN.md §3): the chain state in primary sample space, the
/// perturbations of the inner chain, and the target with coherent (packet) tracing of
/// a bundle's camera rays.
///
/// State. A point of primary sample space is an infinite vector u ∈ [0,1)^∞ laid out as
/// mlt::MltSampler lays it out (3 interleaved streams, 2 slots per dimension). It is
/// stored as a *key* plus sparse overrides: every coordinate not overridden has the
/// value a large step of MltSampler keyed (domain, id, proposal) gives it — a pure
/// Philox function of (seed, key, index). So
///   * a large step is "new key, no overrides" (an independent uniform point);
///   * bootstrap sample i is key (bootstrap, i, 1) — bit for bit the point PSSMLT's
///     bootstrap evaluates — and a chain starts from a resampled bootstrap key with no
///     replay sampler state to carry;
///   * a perturbation copies the overrides and overrides 2 coordinates.
/// Coordinates a path never reads stay at their key's values under the lens, caustic
/// and pixel-move perturbations, which leave them unchanged (δ, a symmetric kernel);
/// the small step refreshes them first (PerturbationProposal) and then steps every
/// coordinate, the unread ones lazily (LazyStep).
///
/// Perturbations (all symmetric on the torus, so mlt_kernels' mtm_step and bundle_step
/// apply unchanged; the kernel draws every candidate of a bundle from the same kernel):
///   * lens: wrapped Gaussian on the film position (camera stream, dimension 0), σ in
///     pixels converted to primary-sample units per axis (σ_pix / W, σ_pix / H). Every
///     other coordinate is kept, so the camera subpath is retraced through its specular
///     vertices with the same BSDF numbers — the primary-sample form of Veach's lens
///     perturbation for (L|D) S* E paths.
///   * caustic: wrapped Gaussian (σ in primary units) on the light stream's emission
///     direction (light-stream dimension 2: after light choice and emission position,
///     BDPT's layout, bdpt_tracer.h) — Veach's caustic perturbation for (L|D) S+ D E
///     paths sampled from the light and connected to the eye (t = 1).
///   * pixel move: the film position redrawn uniformly (a large jump of the film
///     position only), so pixel coverage stays even (the seed's remedy against
///     stratification / blotches).
///   * small step: PSSMLT's wrapped Gaussian on every coordinate (σ in primary units),
///     the technique held, after a refresh of the unread coordinates
///     (PerturbationProposal). Lens and caustic perturbations move two coordinates only, so
///     alone they never explore the rest of the path between large steps; measured on
///     sequences/caustic_glass at 64x64, 256 evaluations per pixel, 3 seeds: relMSE
///     0.0105 without small steps, 0.0084 with half the inner steps small steps, 0.0077
///     with 90 % (pssmlt alone: 0.0085).
/// Choice per inner step (by the kernel RNG, before the bundle is drawn): pixel move with
/// probability k_pixel_move_probability, small step with k_small_step_probability;
/// otherwise caustic if the current path's technique is light tracing (t = 1, the camera
/// vertex connected directly), else lens.
/// The technique (s, t) is part of the state but read from dimensions the lens and
/// caustic perturbations never touch, so every candidate has the same technique as x and
/// the state-dependent choice keeps detailed balance. With the bdpt path sampler (the
/// default, RenderSettings::mlt_path_sampler) light-traced paths — in particular the
/// (L|D) S+ D E caustics seen through the t = 1 connection — take the caustic
/// perturbation; with the pt sampler (technique t = -1) every path takes the lens
/// perturbation.
///
/// Coherence. A bundle's k candidates are k wrapped-Gaussian offsets of one point (mtm:
/// x; bundle: the bundle centre c, itself drawn around x) — Box–Muller Gaussians from
/// the chain's uniforms — so their camera rays are neighbours. Stratified or antithetic
/// offsets would cluster them further, but correlated candidates break the
/// exchangeability that makes bundle_step exact (the joint of x and the y_l would no
/// longer be symmetric), so the offsets are independent given the centre. The target's
/// prepare() traces the k camera rays together: Embree packets (rtcIntersect4/8/16, the
/// smallest width ≥ k the CPU supports natively, inactive lanes masked off), or one by
/// one when packets are off. Either way each mesh hit is refined by the same
/// double-precision ray/triangle intersection (Embree's packet and single-ray kernels
/// differ in the last ulp), so packets on and off give bit-identical images.
#include "accel/accel.h"
#include "integrators/cmlt/bundle_tracer.h"
#include "integrators/mlt/chain_state.h"
#include "integrators/mlt/mlt_sampler.h"
#include "integrators/mlt/pssmlt_tracer.h"
#include "scene/scene.h"
#include "util/cycle_clock.h"
#include "util/error.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <utility>
#include <vector>

namespace cmlt::coherent {

using mlt::MltSampler;
using mlt::PathSample;
using mlt::RngDomain;

/// Probability that an inner step is a pixel move (instead of a lens / caustic
/// perturbation).
inline constexpr double k_pixel_move_probability = 0.1;

/// The large step that generated a point: MltSampler's (domain, id, proposal number).
struct StateKey {
    RngDomain domain = RngDomain::chain;
    uint32_t id = 0;
    uint64_t proposal = 1;
};

/// Value of global primary sample `i` of the point generated by `key` (a large step of
/// MltSampler: the refresh draw's second pair).
inline double key_value(uint64_t seed, const StateKey& key, size_t i) {
    const Philox4x32Counter r = philox4x32(
        mlt::detail::mlt_counter(0, key.domain, key.id, key.proposal, uint32_t(i)), mlt::detail::mlt_key(seed));
    return mlt::detail::bits_to_unit(r[2], r[3]);
}

inline constexpr double k_unset = std::numeric_limits<double>::quiet_NaN();

/// A lazy step of the coordinates a state does not override: either a uniform shift
/// (the small step's refresh of the unread coordinates: key value + a fresh uniform,
/// mod 1, is a fresh uniform) or a wrapped Gaussian step of σ (the small step itself),
/// both drawn per coordinate from (seed, id, index) when the coordinate is read.
struct LazyStep {
    uint64_t id = 0;
    double sigma = -1.0;  ///< < 0: uniform shift; else the Gaussian's σ
};

/// The lazy steps' numbers: one Philox draw per (step, coordinate), tag 4 of the
/// Metropolis counters (0-2: MltSampler's and CounterRng's, 3: temporal keyed uniforms).
inline double lazy_step(uint64_t seed, const LazyStep& step, size_t i) {
    const Philox4x32Counter r = philox4x32(
        mlt::detail::mlt_counter(4, RngDomain::chain, uint32_t(step.id >> 32), step.id & 0xFFFFFFFFu, uint32_t(i)),
        mlt::detail::mlt_key(seed));
    const double a = mlt::detail::bits_to_unit(r[0], r[1]);
    if (step.sigma < 0.0) return a;
    return step.sigma * mlt::detail::box_muller(a, mlt::detail::bits_to_unit(r[2], r[3]));
}

/// A chain state: the point (key + overrides + lazy steps) and, cached by the target,
/// its path.
struct State {
    /// Lazy steps a state can carry: a refresh and two Gaussian levels (the bundle's
    /// centre and candidate, or MTM's candidate and reference point).
    static constexpr size_t k_max_lazy = 3;

    StateKey key;
    std::vector<double> u;  ///< overrides by global index; NaN = the key's value
    /// Steps applied, in order, to every coordinate without an override (see LazyStep).
    std::array<LazyStep, k_max_lazy> lazy{};
    uint32_t lazy_count = 0;
    mutable PathSample sample;  ///< set by the target when the point is evaluated
    /// `sample` is this point's (set by the target; a proposal that writes the point
    /// clears it, so the target evaluates each new point once)
    mutable bool evaluated = false;
    /// Slots per stream the last evaluation read (1 + the highest slot), for export.
    mutable std::array<uint32_t, MltSampler::k_stream_count> extent{};

    double value(uint64_t seed, size_t i) const {
        if (i < u.size() && !std::isnan(u[i])) return u[i];
        double v = key_value(seed, key, i);
        for (uint32_t n = 0; n < lazy_count; ++n) v = mlt::detail::wrap01(v + lazy_step(seed, lazy[n], i));
        return v;
    }
    void add_lazy(const LazyStep& step) {
        CMLT_CHECK_MSG(lazy_count < k_max_lazy, "coherent::State: more than " << k_max_lazy << " lazy steps");
        lazy[lazy_count++] = step;
    }
    void set(size_t i, double v) {
        if (i >= u.size()) u.resize(i + 1, k_unset);
        u[i] = v;
    }
};

/// The path_tracer.h / MltSampler sampler interface over a fixed point (read only).
class PointSampler {
public:
    PointSampler(const State& s, uint64_t seed) : m_state(s), m_seed(seed) {}
    void start_stream(uint32_t stream) {
        m_stream = stream;
        m_dimension = 0;
    }
    void set_dimension(uint32_t d) { m_dimension = d; }
    uint32_t dimension() const { return m_dimension; }
    float get1d() { return to_float(read(m_dimension++ * MltSampler::k_slots_per_dimension)); }
    Vec2 get2d() {
        const uint32_t s = m_dimension++ * MltSampler::k_slots_per_dimension;
        const float a = to_float(read(s));
        const float b = to_float(read(s + 1));
        return {a, b};
    }

private:
    double read(uint32_t slot) const {
        uint32_t& e = m_state.extent[m_stream];
        e = std::max(e, slot + 1);
        return m_state.value(m_seed, MltSampler::index(m_stream, slot));
    }
    static float to_float(double u) {  // as MltSampler
        const float f = float(u);
        return f < 1.f ? f : 0x1.fffffep-1f;
    }
    const State& m_state;
    uint64_t m_seed;
    uint32_t m_stream = MltSampler::camera;
    uint32_t m_dimension = 0;
};

/// Probability that an inner step is a small step of every coordinate (PSSMLT's
/// Gaussian mutation as a bundle) instead of a lens / caustic perturbation.
inline constexpr double k_small_step_probability = 0.5;

/// Perturbation kinds of the inner chain (stats keys).
enum class Perturbation : uint8_t { lens = 0, caustic = 1, pixel_move = 2, small_step = 3 };
inline constexpr size_t k_perturbation_count = 4;
inline const char* perturbation_name(Perturbation p) {
    switch (p) {
        case Perturbation::lens: return "lens";
        case Perturbation::caustic: return "caustic";
        case Perturbation::pixel_move: return "pixel_move";
        case Perturbation::small_step: return "small_step";
    }
    return "unknown";
}

/// Global indices of the coordinates a perturbation changes.
inline size_t film_index(int axis) { return MltSampler::index(MltSampler::camera, uint32_t(axis)); }
inline size_t caustic_index(int axis) {
    constexpr uint32_t k_emission_direction_dimension = 2;  // light choice, position, direction
    return MltSampler::index(MltSampler::light,
                             k_emission_direction_dimension * MltSampler::k_slots_per_dimension + uint32_t(axis));
}

/// A symmetric perturbation (mlt_kernels Proposal concept): two coordinates, or for the
/// small step every coordinate.
///
/// The small step is PSSMLT's wrapped Gaussian on every coordinate (the technique slots
/// held), preceded by a Gibbs refresh of the coordinates the current state x has not
/// read — both leave π invariant, so their composition does:
///   1. refresh: x's coordinates below its extent (those its path read, and the unread
///      ones between) are kept; every other coordinate becomes a fresh uniform (under π
///      they are uniform and independent of the rest, whatever x's key gave them).
///      Without it a coordinate outside the extent stays at the key's value that earlier,
///      rejected proposals read, a proposal reading it for the first time sees that fixed
///      value while the reverse move would perturb it: T(y→x) ≠ T(x→y), and on a target
///      whose paths read a variable number of coordinates (Russian roulette, pass-through
///      surfaces, the pt sampler) the chain drifts (tests/cpp/test_small_step_balance.cpp).
///   2. step: the Gaussian on every coordinate of the refreshed point — eagerly on the
///      overridden ones, lazily (LazyStep, drawn when read) on the rest, so that the
///      candidates of one bundle share the refreshed values and differ by their own
///      Gaussian offsets, as the all-coordinate kernel has it (bundle_step's
///      exchangeability, mtm_step's symmetric T).
/// `refresh` names step 1's uniforms: make() draws it per inner step, and sample() from
/// a point that does not carry it yet (the chain's current state) applies the refresh;
/// from a point that does (the bundle's centre, MTM's chosen candidate) only the step.
struct PerturbationProposal {
    static constexpr bool k_symmetric = true;
    Perturbation kind = Perturbation::lens;
    uint64_t seed = 0;
    size_t i0 = 0, i1 = 0;
    double s0 = 0.01, s1 = 0.01;  ///< σ per coordinate (unused by pixel_move)
    uint64_t refresh = 0;         ///< the small step's refresh (see above)

    /// A proposal of one inner step; the small step draws its refresh from `rng`.
    template <class Rng>
    static PerturbationProposal make(Perturbation kind, uint64_t seed, double sigma_pixels, double sigma_primary,
                                     int width, int height, Rng& rng) {
        PerturbationProposal p;
        p.kind = kind;
        p.seed = seed;
        if (kind == Perturbation::caustic || kind == Perturbation::small_step) {
            p.i0 = caustic_index(0);
            p.i1 = caustic_index(1);
            p.s0 = p.s1 = sigma_primary;
        } else {
            p.i0 = film_index(0);
            p.i1 = film_index(1);
            p.s0 = sigma_pixels / double(width);
            p.s1 = sigma_pixels / double(height);
        }
        if (kind == Perturbation::small_step) p.refresh = draw_id(rng);
        return p;
    }

    template <class Rng>
    void sample(const State& from, State& to, Rng& rng) const {
        to.key = from.key;
        to.evaluated = false;
        if (kind == Perturbation::small_step) {
            const bool refreshed = from.lazy_count > 0 && from.lazy[0].sigma < 0.0 && from.lazy[0].id == refresh;
            if (refreshed) {
                to.u = from.u;  // same-size assignment reuses capacity
                to.lazy = from.lazy;
                to.lazy_count = from.lazy_count;
            } else {
                to.u.clear();
                to.lazy_count = 0;
            }
            // the coordinates below from's extent become overrides (their current values)
            for (uint32_t k = 0; k < MltSampler::k_stream_count; ++k)
                for (uint32_t slot = 0; slot < from.extent[k]; ++slot) {
                    const size_t i = MltSampler::index(k, slot);
                    if (i >= to.u.size() || std::isnan(to.u[i])) to.set(i, from.value(seed, i));
                }
            if (!refreshed) to.add_lazy(LazyStep{refresh, -1.0});
            to.extent = from.extent;
            const size_t t0 = MltSampler::index(MltSampler::connection, 0);
            const size_t t1 = MltSampler::index(MltSampler::connection, 1);
            for (size_t i = 0; i < to.u.size(); ++i) {
                if (std::isnan(to.u[i]) || i == t0 || i == t1) continue;
                to.u[i] = mlt::detail::wrap01(to.u[i] + s0 * rng.normal());
            }
            to.add_lazy(LazyStep{draw_id(rng), s0});
            return;
        }
        to.u = from.u;
        to.lazy = from.lazy;
        to.lazy_count = from.lazy_count;
        if (kind == Perturbation::pixel_move) {
            const double a = rng.uniform();
            const double b = rng.uniform();
            to.set(i0, a);
            to.set(i1, b);
        } else {
            const double a = mlt::detail::wrap01(from.value(seed, i0) + s0 * rng.normal());
            const double b = mlt::detail::wrap01(from.value(seed, i1) + s1 * rng.normal());
            to.set(i0, a);
            to.set(i1, b);
        }
    }

private:
    template <class Rng>
    static uint64_t draw_id(Rng& rng) {
        return uint64_t(rng.uniform() * 0x1p53);
    }
};

/// The outer chain's large step: a new key, no overrides (independent uniform point).
struct LargeStepProposal {
    static constexpr bool k_symmetric = true;
    StateKey next;
    template <class Rng>
    void sample(const State& /*from*/, State& to, Rng& /*rng*/) const {
        to.key = next;
        to.u.clear();
        to.lazy_count = 0;
        to.evaluated = false;
    }
};

/// Does a PathSample carry its BDPT technique (a member `t`)? Then t == 1 (light
/// tracing) selects the caustic perturbation.
template <class S, class = void>
struct has_technique : std::false_type {};
template <class S>
struct has_technique<S, std::void_t<decltype(std::declval<const S&>().t)>> : std::true_type {};

template <class S>
inline bool light_traced(const S& s) {
    if constexpr (has_technique<S>::value) return int(s.t) == 1;
    else return false;
}

/// The target f* of the chains: evaluates points with PssmltTracer, a bundle's
/// candidates together (prepare, the kernels' batch hook), and caches the result in the
/// state (see the file comment).
struct Target {
    const mlt::PssmltTracer* tracer = nullptr;
    const Scene* scene = nullptr;
    uint64_t seed = 0;
    PathCounters* counters = nullptr;
    bool packets = true;
    int max_width = 4;  ///< Accel::max_packet_width()
    BundleCounters* bundle = nullptr;  ///< packet and bundle stats (optional)

    /// f* of one point: its cached value after prepare(), else evaluated alone (scalar
    /// queries; the same code and refined hits as a bundle's lanes).
    double operator()(const State& s) const {
        if (!s.evaluated) evaluate(&s, 1, false);
        return s.sample.f;
    }

    /// The kernels' batch hook: evaluate a bundle's n points together (see the file
    /// comment), timed for the stats.
    void prepare(State* states, size_t n) const {
        BundleCounters local;
        BundleCounters& bc = bundle ? *bundle : local;
        const uint64_t t0 = cycle_now(), trace0 = Accel::trace_ticks(), rays0 = counters->rays;
        evaluate(states, n, packets);
        bc.busy_ticks += cycle_now() - t0;
        bc.trace_ticks += Accel::trace_ticks() - trace0;
        bc.bundle_rays += counters->rays - rays0;
    }

    /// Evaluate states[0..n), their rays in packets if `use_packets`.
    void evaluate(const State* states, size_t n, bool use_packets) const {
        BundleCounters local;
        const RayQueries queries(scene->accel(), use_packets, max_width, bundle ? *bundle : local);
        if (tracer->bdpt()) {
            thread_local BundleEvaluator<State, PointSampler> evaluator;
            evaluator.evaluate(*tracer, *scene, seed, states, n, queries, *counters);
        } else {
            evaluate_pt(states, n, queries);
        }
        for (size_t i = 0; i < n; ++i) states[i].evaluated = true;
    }

private:
    /// The pt path sampler: the camera rays traced together (refined first hits), the
    /// rest of each path by the path tracer alone.
    void evaluate_pt(const State* states, size_t n, const RayQueries& queries) const {
        thread_local std::vector<Ray> rays;
        thread_local std::vector<Hit> hits;
        if (rays.size() < n) {
            rays.resize(n);
            hits.resize(n);
        }
        for (size_t i = 0; i < n; ++i) {
            PointSampler smp(states[i], seed);
            uint32_t pixel;
            rays[i] = tracer->camera_ray(smp, &pixel);
        }
        queries.intersect(rays.data(), n, hits.data());
        for (size_t i = 0; i < n; ++i) {
            refine_hit(*scene, rays[i], hits[i]);
            const SceneHit hit = scene->resolve_hit(rays[i], hits[i]);
            const State& s = states[i];
            s.extent.fill(0);
            PointSampler smp(s, seed);
            s.sample = tracer->evaluate(smp, *counters, &hit);
        }
    }
};

/// A primary sample as the path routines read it (never 1: MltSampler's to_float).
inline float state_float(double u) {
    const float f = float(u);
    return f < 1.f ? f : 0x1.fffffep-1f;
}

/// The point of `s` as an mlt::ChainState (the MltSampler layout the temporal carry-over
/// and pssmlt read): every slot below the last evaluation's extent per stream, the
/// overridden and the key's values alike (unread ones are uniform and independent under
/// the target, so keeping them is exact). Requires `s` to have been evaluated.
inline mlt::ChainState export_state(const State& s, uint64_t seed, uint64_t chain_id) {
    mlt::ChainState out;
    out.chain_id = chain_id;
    for (uint32_t k = 0; k < MltSampler::k_stream_count; ++k) {
        out.u[k].resize(s.extent[k]);
        for (uint32_t slot = 0; slot < s.extent[k]; ++slot)
            out.u[k][slot] = state_float(s.value(seed, MltSampler::index(k, slot)));
    }
    if (s.sample.depth >= 0) {
        out.depth = uint32_t(s.sample.depth);
        out.s = uint32_t(s.sample.s);
        out.t = uint32_t(s.sample.t);
    }
    out.f_star = s.sample.f;
    out.colour = s.sample.L;
    return out;
}

/// A State holding an imported ChainState's values as overrides over `key` (the key's
/// values stand in for the NaN / missing slots: uniform and independent, as a fresh
/// draw would be).
inline State import_state(const mlt::ChainState& c, const StateKey& key) {
    State s;
    s.key = key;
    for (uint32_t k = 0; k < MltSampler::k_stream_count; ++k)
        for (uint32_t slot = 0; slot < c.u[k].size(); ++slot) {
            const float v = c.u[k][slot];
            if (!std::isnan(v)) s.set(MltSampler::index(k, slot), double(v));
        }
    return s;
}

}  // namespace cmlt::coherent
