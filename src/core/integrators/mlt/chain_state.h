#pragma once
/// \file Export / import of PSSMLT chain states (temporal carry-over of chains from one
/// frame to the next, src/core/temporal/).
///
/// A ChainState is the Markov chain's state x in primary sample space: per stream
/// (camera, light, connection; MltSampler layout, slot s = the s-th number the path
/// routine reads on that stream, two slots per sampler dimension) the values of the
/// coordinates the current path read, NaN for a coordinate the state has no value of
/// its own (drawn afresh from a uniform when a later path reads it — exact: such a
/// coordinate is uniform and independent under the target). With the "bdpt" path
/// sampler the technique is u[connection][0..1] (technique.h); `depth`, `s`, `t` are
/// what it decoded to (informational: on import u is authoritative, the technique is
/// decoded again under the new frame's max_depth). `f_star` and `colour` (= L, so
/// luminance(colour) = f_star) are the state's values in the frame that exported it;
/// on import the state is re-evaluated in the new scene.
///
/// RenderSettings::mlt_initial_states (if set and non-empty) replaces the bootstrap
/// resampling: chain c starts from states.chains[c] (the chain count is then the number
/// of states; the bootstrap still runs, for b). RenderResult::mlt_states holds the final
/// state of every chain after a pssmlt or cmlt render, chain_id carried over from the
/// imported state (else the chain's index). Chain c's random numbers are keyed by (seed, c),
/// never by chain_id.
///
/// Byte format (to_bytes / from_bytes), little-endian:
///   "CMLTMCS1" | u32 path_sampler (0 pt, 1 bdpt) | u32 reserved 0 | u64 n_chains |
///   n × { u64 chain_id | u32 depth, s, t | f64 f_star | 3 × f32 colour |
///         3 × { u32 n | n × f32 } }
#include "math/vec.h"

#include <array>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

namespace cmlt::mlt {

struct ChainState {
    uint64_t chain_id = 0;
    std::array<std::vector<float>, 3> u;  ///< per stream: slot values, NaN = no value
    uint32_t depth = 0, s = 0, t = 0;     ///< technique (bdpt); 0, 0, 0 for the pt sampler
    double f_star = 0.0;
    Spectrum colour{0.f};
};

/// The state chain c of n starts from when a frame runs n < `given` chains of a
/// population of `given` states (RenderSettings::mlt_initial_states; the budget caps the
/// chain count): an even stride over the whole population, state ⌊(2c + 1)·given / 2n⌋,
/// never just the first n. The temporal driver lists its starts in chain order, and in
/// that order the starts follow their bootstrap index (systematic resampling is sorted),
/// so the first n would be a resampling of the first n/given of the bootstrap pool only.
/// With n = given, chain c starts from state c.
inline size_t subsampled_state(uint64_t c, uint64_t n, uint64_t given) {
    return size_t((2 * c + 1) * given / (2 * n));
}

struct ChainStates {
    std::string path_sampler = "bdpt";  ///< "pt" | "bdpt": the u layout
    std::vector<ChainState> chains;

    std::string to_bytes() const {
        std::string b;
        auto put = [&b](const void* p, size_t n) { b.append(static_cast<const char*>(p), n); };
        auto put32 = [&](uint32_t v) { put(&v, 4); };
        auto put64 = [&](uint64_t v) { put(&v, 8); };
        put("CMLTMCS1", 8);
        put32(path_sampler == "pt" ? 0u : 1u);
        put32(0u);
        put64(chains.size());
        for (const ChainState& c : chains) {
            put64(c.chain_id);
            put32(c.depth);
            put32(c.s);
            put32(c.t);
            put(&c.f_star, 8);
            const float col[3] = {c.colour.x, c.colour.y, c.colour.z};
            put(col, 12);
            for (const auto& v : c.u) {
                put32(uint32_t(v.size()));
                if (!v.empty()) put(v.data(), v.size() * 4);
            }
        }
        return b;
    }

    /// Throws std::invalid_argument on a malformed buffer.
    static ChainStates from_bytes(const std::string& b) {
        size_t pos = 0;
        auto get = [&](void* p, size_t n) {
            if (b.size() - pos < n || pos > b.size())
                throw std::invalid_argument("MltStates.from_bytes: truncated buffer");
            std::memcpy(p, b.data() + pos, n);
            pos += n;
        };
        auto get32 = [&] { uint32_t v; get(&v, 4); return v; };
        auto get64 = [&] { uint64_t v; get(&v, 8); return v; };
        char magic[8];
        get(magic, 8);
        if (std::memcmp(magic, "CMLTMCS1", 8) != 0)
            throw std::invalid_argument("MltStates.from_bytes: not a chain-state buffer (bad magic)");
        ChainStates out;
        const uint32_t sampler = get32();
        if (sampler > 1) throw std::invalid_argument("MltStates.from_bytes: unknown path sampler");
        out.path_sampler = sampler == 0 ? "pt" : "bdpt";
        get32();
        const uint64_t n = get64();
        if (n > b.size()) throw std::invalid_argument("MltStates.from_bytes: bad chain count");
        out.chains.resize(size_t(n));
        for (ChainState& c : out.chains) {
            c.chain_id = get64();
            c.depth = get32();
            c.s = get32();
            c.t = get32();
            get(&c.f_star, 8);
            float col[3];
            get(col, 12);
            c.colour = Spectrum(col[0], col[1], col[2]);
            for (auto& v : c.u) {
                const uint32_t m = get32();
                if (size_t(m) * 4 > b.size() - pos)
                    throw std::invalid_argument("MltStates.from_bytes: truncated buffer");
                v.resize(m);
                if (m) get(v.data(), size_t(m) * 4);
            }
        }
        if (pos != b.size()) throw std::invalid_argument("MltStates.from_bytes: trailing bytes");
        return out;
    }
};

}  // namespace cmlt::mlt
