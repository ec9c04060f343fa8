// Tests of the MCMC kernels: a small deterministic random number generator.
//
// Every kernel of src/core/mcmc is a template over an RNG type with two methods:
//   double uniform();  // in [0, 1)
//   double normal();   // standard normal N(0, 1)
// The renderer passes its counter-based streams (sampling/rng.h's CounterRng, keyed by
// (shot seed, domain, chain)); the toy tests use TestRng: xoshiro256++ seeded through
// splitmix64, with Box–Muller normals. Both are fully deterministic.
#pragma once

#include <cmath>
#include <cstdint>

namespace cmlt::mcmc::testing {

/// splitmix64 step (Steele, Lea, Flood 2014): advances `state` and returns a
/// well-mixed 64-bit value. Used to expand seeds.
inline std::uint64_t splitmix64(std::uint64_t& state) {
  std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

/// Deterministic test RNG: xoshiro256++ (Blackman & Vigna 2019), state seeded from
/// (seed, stream) through splitmix64 so that nearby seeds give unrelated streams.
class TestRng {
 public:
  explicit TestRng(std::uint64_t seed, std::uint64_t stream = 0) {
    std::uint64_t sm = seed ^ (0xD1B54A32D192ED03ull * (stream + 1));
    sm = splitmix64(sm) ^ stream;  // decorrelate (seed, stream) pairs
    for (auto& word : m_s) word = splitmix64(sm);
  }

  /// Next raw 64-bit output (xoshiro256++).
  std::uint64_t next_u64() {
    const std::uint64_t result = rotl(m_s[0] + m_s[3], 23) + m_s[0];
    const std::uint64_t t = m_s[1] << 17;
    m_s[2] ^= m_s[0];
    m_s[3] ^= m_s[1];
    m_s[1] ^= m_s[2];
    m_s[0] ^= m_s[3];
    m_s[2] ^= t;
    m_s[3] = rotl(m_s[3], 45);
    return result;
  }

  /// Uniform double in [0, 1) with 53 random bits (never returns 1).
  double uniform() { return static_cast<double>(next_u64() >> 11) * 0x1.0p-53; }

  /// Standard normal by Box–Muller; the second value of each pair is cached, so the
  /// sequence is deterministic given the seed and the order of calls.
  double normal() {
    if (m_has_spare) {
      m_has_spare = false;
      return m_spare;
    }
    const double u1 = 1.0 - uniform();  // (0, 1]: log never sees 0
    const double u2 = uniform();
    const double r = std::sqrt(-2.0 * std::log(u1));
    const double phi = 6.283185307179586476925 * u2;
    m_spare = r * std::sin(phi);
    m_has_spare = true;
    return r * std::cos(phi);
  }

 private:
  static std::uint64_t rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

  std::uint64_t m_s[4] = {};
  double m_spare = 0.0;
  bool m_has_spare = false;
};

}  // namespace cmlt::mcmc::testing
