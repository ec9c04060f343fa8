#pragma once
/// \file Coherent MLT (DESIGN.md §3): the perturbations of the inner chain — proposals
/// on the chain state (cmlt_state.h) meant to be symmetric, so that mcmc's mtm_step and
/// bundle_step apply unchanged; the kernel draws every candidate of a bundle from the
/// same kernel. Lens, caustic and pixel move are symmetric on the whole point (they
/// change two coordinates and keep every other, read or not). The small step is not
/// exactly symmetric when a candidate's path reads coordinates the current path did not
/// (see PerturbationProposal::sample).
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
///     the technique held. Lens and caustic perturbations move two coordinates only, so
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

/// A symmetric perturbation of two coordinates (mcmc/proposals.h Proposal concept).
struct PerturbationProposal {
    static constexpr bool k_symmetric = true;
    Perturbation kind = Perturbation::lens;
    uint64_t seed = 0;
    size_t i0 = 0, i1 = 0;
    double s0 = 0.01, s1 = 0.01;  ///< σ per coordinate (unused by pixel_move)

    static PerturbationProposal make(Perturbation kind, uint64_t seed, double sigma_pixels, double sigma_primary,
                                     int width, int height) {
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
        return p;
    }

    template <class Rng>
    void sample(const State& from, State& to, Rng& rng) const {
        to.key = from.key;
        to.u = from.u;  // same-size assignment reuses capacity
        to.evaluated = false;
        if (kind == Perturbation::small_step) {
            // Every materialised coordinate (overridden, or read by the path of `from`)
            // gets a wrapped Gaussian step; the technique slots stay (multiplexed MLT,
            // mlt_sampler.h). A coordinate never materialised keeps its key value. That
            // is not PSSMLT's lazy mutation (Kelemen et al. 2002: a number first read by
            // the proposal is drawn afresh): a candidate whose path reads a coordinate
            // `from`'s path did not sees the fixed key value, while the reverse move
            // would perturb it, so T(x→y) ≠ T(y→x) on paths of different lengths (pass-
            // through crossings, the pt sampler) and the chains drift from π (a toy
            // target: tests/bench/results/cmlt_small_steps.md).
            for (uint32_t k = 0; k < MltSampler::k_stream_count; ++k)
                for (uint32_t slot = 0; slot < from.extent[k]; ++slot) {
                    const size_t i = MltSampler::index(k, slot);
                    if (i >= to.u.size() || std::isnan(to.u[i])) to.set(i, key_value(seed, from.key, i));
                }
            to.extent = from.extent;
            const size_t t0 = MltSampler::index(MltSampler::connection, 0);
            const size_t t1 = MltSampler::index(MltSampler::connection, 1);
            for (size_t i = 0; i < to.u.size(); ++i) {
                if (std::isnan(to.u[i]) || i == t0 || i == t1) continue;
                to.u[i] = wrap01(to.u[i] + s0 * rng.normal());
            }
            return;
        }
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
};

/// The outer chain's large step: a new key, no overrides (independent uniform point).
struct LargeStepProposal {
    static constexpr bool k_symmetric = true;
    StateKey next;
    template <class Rng>
    void sample(const State& /*from*/, State& to, Rng& /*rng*/) const {
        to.key = next;
        to.u.clear();
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
