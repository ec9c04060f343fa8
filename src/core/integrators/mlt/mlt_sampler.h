#pragma once
/// \file Primary-sample-space Metropolis sampler (Kelemen et al. 2002, "A simple and
/// robust mutation strategy for the Metropolis light transport algorithm", §3–4).
///
/// The Markov chain state is an (unbounded) vector of primary samples u ∈ [0,1)^∞, read
/// by a path-sampling routine through the small sampler interface of path_tracer.h
/// (`set_dimension`, `get1d`, `get2d`). Mutations are *lazy* (pbrt-v4 `MLTSampler`):
/// each primary sample remembers the iteration at which it was last brought up to date,
/// and is only mutated when it is read:
///   * a large step accepted since then → the sample is a fresh uniform number;
///   * otherwise n small steps were accepted since then → the accumulated wrapped
///     Gaussian, one draw with σ√n (the sum of n independent N(0, σ²) is N(0, nσ²),
///     and wrapping onto the torus commutes with adding);
///   * a sample never read before is a fresh uniform number (it is part of the current
///     state, whose unread coordinates are uniform and independent), then mutated.
/// `reject()` restores every sample touched by the rejected proposal bit-exactly (stored
/// value and modification iteration, as before the proposal read it) and reuses the
/// iteration number, so iterations count accepted steps only.
///
/// Streams (pbrt-v4; Hachisuka et al. 2014): `k_stream_count` = 3 interleaved index
/// spaces — camera, light, connection — so a camera subpath that reads more or fewer
/// dimensions never shifts the light subpath's samples. Global index of slot s of
/// stream k: `k + 3·s`. One sampler *dimension* owns two slots (`get2d` reads both,
/// `get1d` the first), matching PixelSampler where a dimension yields up to two numbers.
///
/// Frozen slots: `freeze_in_small_steps(stream, slots)` exempts the first `slots` slots of
/// one stream from small steps (they change only at large steps). Multiplexed MLT over
/// BDPT keeps its technique (depth, s, t: connection stream, dimension 0, technique.h)
/// this way: a small step is then a symmetric Gaussian walk on the other coordinates
/// with the technique coordinates held (a δ kernel on them, also symmetric), so
/// T(x→y) = T(y→x) still holds; large steps redraw them and keep the chain ergodic.
/// (pbrt-v4's MLTIntegrator does perturb its strategy sample in small steps — valid too,
/// but a crossing of a strategy boundary then reinterprets every sample of the path, a
/// near-certain rejection dressed as a small step.)
///
/// Export / import (chain-state carry-over): `current_state()` returns the coordinates
/// the current path read (last modified at the current iteration) per stream, NaN for
/// the others — those do not enter f*(x) and are, under the target, uniform and
/// independent, so a fresh uniform on import is exact. `import_state()` installs such a
/// vector; `begin_replay()` / `end_replay()` bracket one evaluation of the imported
/// state without mutation (a NaN / unread coordinate it reads gets a fresh uniform and
/// becomes part of the state).
///
/// Random numbers are a pure function of (seed, domain, id, proposal number, sample
/// index) through Philox-4x32 (the Metropolis counters of sampling/rng_domains.h): a
/// chain's numbers depend neither on the thread that runs it nor on the order in which
/// dimensions are read. The proposal number counts every proposal, rejected ones
/// included (never reused). Control numbers (large-step choice, acceptance) come from a
/// second, sequential counter (CounterRng).
#include "math/vec.h"
#include "sampling/rng.h"

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace cmlt::mlt {

/// Luminance weights of the rendering space (ACEScg, AP1 primaries, D60 white): the
/// Y row of the AP1→XYZ matrix. f* = luminance of the path contribution.
inline constexpr double k_luminance_weights[3] = {0.2722287, 0.6740818, 0.0536895};

/// f*(L): ACEScg luminance of a path contribution; 0 for a non-finite colour or a
/// non-positive luminance (such a path can never be accepted).
inline double target_luminance(const Spectrum& L) {
    const double y = k_luminance_weights[0] * double(L.x) + k_luminance_weights[1] * double(L.y) +
                     k_luminance_weights[2] * double(L.z);
    return (std::isfinite(y) && y > 0.0) ? y : 0.0;
}

// The counter spaces and the chains' sequential generator live in the RNG module
// (sampling/rng_domains.h, sampling/rng.h); the Metropolis room names them here too.
using cmlt::CounterRng;
using cmlt::RngDomain;

/// The Metropolis sampler of one chain (see the file comment).
class MltSampler {
public:
    static constexpr uint32_t k_stream_count = 3;
    enum Stream : uint32_t { camera = 0, light = 1, connection = 2 };
    static constexpr uint32_t k_slots_per_dimension = 2;

    /// One primary sample with its backup for reject().
    struct PrimarySample {
        static constexpr int64_t k_unread = std::numeric_limits<int64_t>::min();
        double value = 0.0;
        int64_t last_modified = k_unread;  ///< iteration it is up to date at
        double value_backup = 0.0;
        int64_t modified_backup = k_unread;
    };

    /// `sigma`: small-step standard deviation per primary sample, > 0;
    /// `large_step_probability` ∈ [0, 1]. Numbers keyed by (seed, domain, id).
    MltSampler(uint64_t seed, double sigma, double large_step_probability,
               RngDomain domain = RngDomain::chain, uint32_t id = 0)
        : m_seed(seed), m_key(seed_key(seed)), m_domain(domain), m_id(id), m_sigma(sigma),
          m_large_step_probability(large_step_probability), m_control(seed, domain, id) {}

    /// Switch the numbers to (domain, id) — e.g. a chain started from bootstrap sample j
    /// replays it under (bootstrap, j), then continues under (chain, c). The state is kept.
    void set_key(RngDomain domain, uint32_t id) {
        m_domain = domain;
        m_id = id;
        m_control = CounterRng(m_seed, domain, id);
    }

    // ---- Markov chain control ----------------------------------------------------
    /// Begin a proposal; a large step with probability large_step_probability (drawn
    /// from the control stream). Returns true for a large step.
    bool start_iteration() {
        const bool large = m_large_step_probability >= 1.0 ||
                           (m_large_step_probability > 0.0 && m_control.uniform() < m_large_step_probability);
        start_iteration(large);
        return large;
    }
    /// Begin a proposal of the given kind.
    void start_iteration(bool large_step) {
        ++m_iteration;
        ++m_proposal;
        m_large_step = large_step;
        start_stream(camera);
    }
    /// Keep the proposal as the new state.
    void accept() {
        if (m_large_step) m_last_large_step = m_iteration;
    }
    /// Discard the proposal: restore every sample it touched, bit for bit.
    void reject() {
        for (PrimarySample& x : m_x)
            if (x.last_modified == m_iteration) {
                x.value = x.value_backup;
                x.last_modified = x.modified_backup;
            }
        --m_iteration;
    }

    /// Exempt slots [0, slots) of `stream` from small steps (see the file comment).
    void freeze_in_small_steps(uint32_t stream, uint32_t slots) {
        m_frozen_stream = stream;
        m_frozen_slots = slots;
    }

    /// Per stream, the value of slot s of the current state (the coordinates the current
    /// path read), NaN where the current state has no value of its own. Call between
    /// steps (after accept / reject).
    std::array<std::vector<double>, k_stream_count> current_state() const {
        std::array<std::vector<double>, k_stream_count> u;
        const double nan = std::numeric_limits<double>::quiet_NaN();
        for (size_t i = 0; i < m_x.size(); ++i) {
            const PrimarySample& x = m_x[i];
            if (x.last_modified != m_iteration || x.last_modified == PrimarySample::k_unread) continue;
            std::vector<double>& v = u[i % k_stream_count];
            const size_t slot = i / k_stream_count;
            if (v.size() <= slot) v.resize(slot + 1, nan);
            v[slot] = x.value;
        }
        return u;
    }

    /// Replace the state by `u` (per stream, slot values in [0, 1); NaN or missing =
    /// no value: drawn afresh when first read). The iteration counters restart; the
    /// proposal counter (which keys the numbers) is kept. Follow with begin_replay(),
    /// one evaluation, end_replay() to know f* of the state.
    template <class Vector>
    void import_state(const std::array<Vector, k_stream_count>& u) {
        m_x.clear();
        m_iteration = 0;
        m_last_large_step = 0;
        m_large_step = false;
        for (uint32_t k = 0; k < k_stream_count; ++k)
            for (size_t slot = 0; slot < u[k].size(); ++slot) {
                const double v = double(u[k][slot]);
                if (!(v >= 0.0 && v < 1.0)) continue;  // NaN / out of range: no value
                const size_t i = index(k, uint32_t(slot));
                if (i >= m_x.size()) m_x.resize(i + 1);
                m_x[i].value = v;
                m_x[i].last_modified = m_iteration;
            }
    }
    /// Evaluate the current state without mutating it (see import_state).
    void begin_replay() {
        m_replay = true;
        ++m_proposal;
        start_stream(camera);
    }
    void end_replay() { m_replay = false; }

    bool large_step() const { return m_large_step; }
    int64_t iteration() const { return m_iteration; }
    uint64_t proposals() const { return m_proposal; }

    // ---- sampler interface (path_tracer.h) ---------------------------------------
    /// Select a stream and rewind it to dimension 0.
    void start_stream(uint32_t stream) {
        m_stream = stream;
        m_dimension = 0;
    }
    void set_dimension(uint32_t d) { m_dimension = d; }
    uint32_t dimension() const { return m_dimension; }

    float get1d() {
        const size_t i = index(m_stream, m_dimension++ * k_slots_per_dimension);
        return unit_float(sample(i));
    }
    Vec2 get2d() {
        const uint32_t s = m_dimension++ * k_slots_per_dimension;
        const float a = unit_float(sample(index(m_stream, s)));
        const float b = unit_float(sample(index(m_stream, s + 1)));
        return {a, b};
    }

    // ---- kernel RNG interface (control stream) -----------------------------------
    double uniform() { return m_control.uniform(); }
    double normal() { return m_control.normal(); }

    // ---- introspection (tests, state dumps) --------------------------------------
    /// Global index of slot `slot` of `stream`.
    static size_t index(uint32_t stream, uint32_t slot) {
        return size_t(stream) + size_t(k_stream_count) * size_t(slot);
    }
    /// The stored samples (not caught up: a sample that lags behind is mutated on read).
    const std::vector<PrimarySample>& samples() const { return m_x; }
    /// Read global sample i as the path routine would (mutating it lazily), in double.
    double sample(size_t i) {
        ensure_ready(i);
        return m_x[i].value;
    }

private:
    /// Two numbers of sample i at the current proposal: [0] refresh, [1] proposal value.
    Philox4x32Counter draw(size_t i) const {
        return philox4x32(metropolis_counter(RngTag::point, m_domain, m_id, m_proposal, uint32_t(i)), m_key);
    }

    void ensure_ready(size_t i) {
        if (i >= m_x.size()) m_x.resize(i + 1);
        PrimarySample& x = m_x[i];
        if (x.last_modified == m_iteration && x.last_modified != PrimarySample::k_unread)
            return;  // already mutated by this proposal
        const Philox4x32Counter r = draw(i);
        if (m_replay) {  // evaluating the state itself: only coordinates without a value move
            if (x.last_modified == PrimarySample::k_unread) {
                x.value = bits_to_unit(r[0], r[1]);
                x.last_modified = m_iteration;
            }
            return;
        }
        // back up the stored sample as it is, so reject() restores it bit for bit
        x.value_backup = x.value;
        x.modified_backup = x.last_modified;

        // bring the current state's value up to date. An unread or stale sample does not
        // enter f*(x) (x's path did not read it), so under π it is uniform and independent
        // of everything else: drawing it afresh is a Gibbs update of that coordinate, valid
        // whenever it happens — also again after a reject restored the stale value.
        if (x.last_modified == PrimarySample::k_unread) {
            x.value = bits_to_unit(r[0], r[1]);   // unread: uniform, part of x
            x.last_modified = m_iteration - 1;
        } else if (x.last_modified < m_last_large_step) {
            x.value = bits_to_unit(r[0], r[1]);   // a large step was accepted since
            x.last_modified = m_last_large_step;
        }

        // mutate: fresh uniform, or the accumulated small steps σ√n (wrapped)
        if (m_large_step) {
            x.value = bits_to_unit(r[2], r[3]);
        } else if (m_frozen_slots > 0 && i % k_stream_count == m_frozen_stream &&
                   i / k_stream_count < m_frozen_slots) {
            // held by small steps (technique samples): the value stays
        } else {
            const int64_t n = m_iteration - x.last_modified;
            const Philox4x32Counter g =
                philox4x32(metropolis_counter(RngTag::small_step, m_domain, m_id, m_proposal, uint32_t(i)), m_key);
            const double z = box_muller(bits_to_unit(g[0], g[1]), bits_to_unit(g[2], g[3]));
            x.value = wrap01(x.value + m_sigma * std::sqrt(double(n)) * z);
        }
        x.last_modified = m_iteration;
    }

    uint64_t m_seed;
    Philox4x32Key m_key;
    RngDomain m_domain;
    uint32_t m_id;
    double m_sigma;
    double m_large_step_probability;
    CounterRng m_control;

    std::vector<PrimarySample> m_x;
    int64_t m_iteration = 0;        ///< accepted iterations + the current proposal
    int64_t m_last_large_step = 0;  ///< iteration of the last accepted large step
    uint64_t m_proposal = 0;        ///< every proposal, never reused (keys the numbers)
    bool m_large_step = true;
    bool m_replay = false;
    uint32_t m_frozen_stream = connection;
    uint32_t m_frozen_slots = 0;  ///< slots of m_frozen_stream held by small steps
    uint32_t m_stream = camera;
    uint32_t m_dimension = 0;
};

}  // namespace cmlt::mlt
