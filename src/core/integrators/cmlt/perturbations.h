#pragma once
/// \file Coherent MLT (DESIGN.md §3): the perturbations of the inner chain — proposals
/// on the chain state (cmlt_state.h) meant to be symmetric, so that mcmc's mtm_step and
/// bundle_step apply unchanged; the kernel draws every candidate of a bundle from the
/// same kernel. Lens, caustic and pixel move are symmetric on the whole point (they
/// change two coordinates and keep every other, read or not). The small step refreshes
/// the coordinates the current path did not read and then steps every coordinate
/// (PerturbationProposal), which is exact also when a candidate's path reads more
/// coordinates than the current one (tests/cpp/mcmc/test_small_step_balance.cpp).
///
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
///     the technique held, after a refresh of the unread coordinates. Lens and caustic perturbations move two coordinates only, so
///     alone they never explore the rest of the path between large steps (measured:
///     tests/bench/results/cmlt_small_steps.md).
/// Choice per inner step (choose_perturbation, by the kernel RNG, before the bundle is
/// drawn): pixel move with probability k_pixel_move_probability, small step with
/// k_small_step_probability; otherwise caustic if the current path's technique is light
/// tracing (t = 1, the camera vertex connected directly), else lens.
/// The technique (s, t) is part of the state but read from dimensions the lens and
/// caustic perturbations never touch, so every candidate has the same technique as x and
/// the state-dependent choice keeps detailed balance. With the bdpt path sampler (the
/// default, RenderSettings::mlt_path_sampler) light-traced paths — in particular the
/// (L|D) S+ D E caustics seen through the t = 1 connection — take the caustic
/// perturbation; with the pt sampler (technique t = -1) every path takes the lens
/// perturbation.
///
/// The outer chain's large step (LargeStepProposal) is a new key with no overrides.
#include "integrators/cmlt/cmlt_settings.h"
#include "integrators/cmlt/cmlt_state.h"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <utility>

namespace cmlt::coherent {

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

/// A symmetric perturbation (mcmc/proposals.h Proposal concept): two coordinates, or for
/// the small step every coordinate.
///
/// The small step is PSSMLT's wrapped Gaussian on every coordinate (the technique slots
/// held), preceded by a Gibbs refresh of the coordinates the current state x has not
/// read — both leave π invariant, so their composition does:
///   1. refresh: x's coordinates below its extent (those its path read, and the unread
///      ones between) are kept; every other coordinate becomes a fresh uniform (under π
///      they are uniform and independent of the rest, whatever x's key gave them).
///      Without it a coordinate outside the extent stays at the key's value that earlier,
///      rejected proposals read: a proposal reading it for the first time sees that fixed
///      value while the reverse move would perturb it, T(y→x) ≠ T(x→y), and on a target
///      whose paths read a variable number of coordinates (Russian roulette, pass-through
///      surfaces, the pt sampler) the chains drift (test_small_step_balance.cpp: to
///      π(u0 < 1/2) ≈ 0.52 instead of 0.478).
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
                to.u[i] = wrap01(to.u[i] + s0 * rng.normal());
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
            const double a = wrap01(from.value(seed, i0) + s0 * rng.normal());
            const double b = wrap01(from.value(seed, i1) + s1 * rng.normal());
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

/// The perturbation of an inner step from the current state `x` and the kernel's
/// uniform `u` (see the file comment).
inline Perturbation choose_perturbation(double u, const State& x) {
    if (u < k_pixel_move_probability) return Perturbation::pixel_move;
    if (u < k_pixel_move_probability + k_small_step_probability) return Perturbation::small_step;
    if (light_traced(x.sample)) return Perturbation::caustic;
    return Perturbation::lens;
}

}  // namespace cmlt::coherent
