#pragma once
/// \file How long Markov chains sit in one state, and how unevenly a population's splat
/// weight is spread over its chains: rejection streaks, the occupancy statistic of
/// "stuck" chains and the chains' shares, per chain and merged over the population in
/// chain order. Generic (no rendering types); the Metropolis integrators report them as
/// MltStats::max_rejection_streak, long_streak_rejections, states_visited,
/// top_occupancy, max_chain_share, stuck_chains and max_stay_share
/// (integrators/mlt/chain_population.h).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <map>
#include <vector>

namespace cmlt::mcmc {

/// How long chains sit in one state. A state is occupied for 1 + (rejections that
/// follow) steps; `top_fraction(q)` is the share of all steps spent in the most-occupied
/// fraction q of the states visited (the "no chain sticks" measure: with q = 0.1 %
/// a healthy chain population gives a few percent, a stuck one most of its steps).
class Occupancy {
public:
    void add_run(uint64_t steps) {
        if (steps == 0) return;
        if (steps < k_dense) ++m_dense[steps];
        else ++m_sparse[steps];
        m_total += steps;
        ++m_states;
    }
    void merge(const Occupancy& o) {
        for (size_t i = 0; i < k_dense; ++i) m_dense[i] += o.m_dense[i];
        for (const auto& kv : o.m_sparse) m_sparse[kv.first] += kv.second;
        m_total += o.m_total;
        m_states += o.m_states;
    }
    uint64_t states() const { return m_states; }
    uint64_t steps() const { return m_total; }
    double top_fraction(double q) const {
        if (m_total == 0) return 0.0;
        uint64_t take = uint64_t(std::ceil(q * double(m_states)));
        uint64_t sum = 0;
        for (auto it = m_sparse.rbegin(); it != m_sparse.rend() && take > 0; ++it) {
            const uint64_t k = std::min(take, it->second);
            sum += k * it->first;
            take -= k;
        }
        for (size_t len = k_dense; len-- > 1 && take > 0;) {
            const uint64_t k = std::min(take, m_dense[len]);
            sum += k * len;
            take -= k;
        }
        return double(sum) / double(m_total);
    }

private:
    static constexpr size_t k_dense = 256;
    uint64_t m_dense[k_dense] = {};
    std::map<uint64_t, uint64_t> m_sparse;
    uint64_t m_total = 0, m_states = 0;
};

/// Rejection runs and occupancy of one chain.
struct StreakTracker {
    static constexpr uint64_t k_long_streak = 1000;  ///< "stuck" rejection run (stats)
    uint64_t streak = 0, max_streak = 0, long_streak_rejections = 0;
    Occupancy occupancy;

    void record(bool moved) {
        if (moved) {
            end();
        } else {
            max_streak = std::max(max_streak, ++streak);
        }
    }
    void merge(const StreakTracker& o) {
        max_streak = std::max(max_streak, o.max_streak);
        long_streak_rejections += o.long_streak_rejections;
        occupancy.merge(o.occupancy);
    }
    /// The current state's run ends (a move, or the end of the frame).
    void end() {
        if (streak > k_long_streak) long_streak_rejections += streak;
        occupancy.add_run(streak + 1);
        streak = 0;
    }
};

/// Where one chain's splat weight went, in luminance (Σ w · luminance(L) / f* over its
/// splats: the chain's part of the image's luminance, up to the frame's common factor
/// b·W·H / steps). `stay` is the weight put on the chain's current state since it moved
/// there, `max_stay` the heaviest stay so far.
struct ChainShare {
    double weight = 0.0, stay = 0.0, max_stay = 0.0;

    /// A splat of luminance weight `w`; `current`: on the chain's current state.
    void add(double w, bool current) {
        weight += w;
        if (current) stay += w;
    }
    /// The current state's stay ends (a move, or the end of the frame).
    void end_stay() {
        max_stay = std::max(max_stay, stay);
        stay = 0.0;
    }
};

/// The chains' shares of the frame's Metropolis splat luminance (MltStats::
/// max_chain_share, stuck_chains, max_stay_share). Chains are added in chain order, so
/// the sums are the same at any thread count. A chain is stuck when its share exceeds
/// k_stuck_factor times the fair share 1/n, or when it rejected StreakTracker::
/// k_long_streak proposals in a row.
class ShareSummary {
public:
    /// k: on cornell (64 evaluations per pixel, 1000 chains, 16 seeds each of pssmlt and
    /// cmlt) the largest share of a healthy population is at most ~30x the fair share
    /// (the pixel target weighs the chains' splats by where they go); 100 leaves room.
    static constexpr double k_stuck_factor = 100.0;

    void add(const ChainShare& c, uint64_t max_streak) {
        m_weights.push_back(c.weight);
        m_long.push_back(max_streak >= StreakTracker::k_long_streak);
        m_total += c.weight;
        m_max_stay = std::max(m_max_stay, c.max_stay);
    }
    double total() const { return m_total; }
    /// The largest share of one chain (0 without splats).
    double max_share() const {
        double m = 0.0;
        for (double w : m_weights) m = std::max(m, w);
        return m_total > 0.0 ? m / m_total : 0.0;
    }
    /// The heaviest stay of any chain, as a share of all chains' weight.
    double max_stay_share() const { return m_total > 0.0 ? m_max_stay / m_total : 0.0; }
    /// Chains above k_stuck_factor / n, n the chains that splatted (a part of a frame,
    /// RenderSettings::partial, runs only its own chains), or with a long rejection run.
    uint64_t stuck() const {
        double n = 0.0;
        for (double w : m_weights) n += w > 0.0 ? 1.0 : 0.0;
        uint64_t out = 0;
        for (size_t i = 0; i < m_weights.size(); ++i)
            out += (m_long[i] || (m_total > 0.0 && m_weights[i] / m_total > k_stuck_factor / n)) ? 1 : 0;
        return out;
    }

private:
    std::vector<double> m_weights;
    std::vector<bool> m_long;
    double m_total = 0.0, m_max_stay = 0.0;
};

}  // namespace cmlt::mcmc
