// cmlt — Metropolis kernels: per-step results and per-mutation-type chain statistics.
//
// Every kernel returns a StepResult; a ChainStats accumulates them per mutation type,
// and KernelStats holds one ChainStats per MutationKind and writes the JSON object that
// the renderer puts into its per-frame stats sidecar.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <ostream>

namespace cmlt::mcmc {

/// Which kernel produced a step. The names are the spelling used in settings and JSON.
enum class MutationKind : std::uint8_t {
  small_step = 0,  ///< single-proposal Metropolis, wrapped Gaussian (PSSMLT small step)
  large_step = 1,  ///< single-proposal Metropolis, independent uniform proposal
  mtm = 2,         ///< multiple-try Metropolis, exact splatting (y* with a, x with 1−a)
  seed = 3,        ///< multiple-try Metropolis, the seminar's 2k splatting rule (biased)
  bundle = 4,      ///< multiple-proposal MH on a coherent bundle (Tjelmeland 2004)
};
inline constexpr std::size_t k_mutation_kind_count = 5;

inline const char* mutation_kind_name(MutationKind kind) {
  switch (kind) {
    case MutationKind::small_step: return "small_step";
    case MutationKind::large_step: return "large_step";
    case MutationKind::mtm: return "mtm";
    case MutationKind::seed: return "seed";
    case MutationKind::bundle: return "bundle";
  }
  return "unknown";
}

/// What one kernel step did.
struct StepResult {
  MutationKind kind = MutationKind::small_step;
  bool moved = false;       ///< the chain state changed (proposal / candidate accepted)
  double acceptance = 0.0;  ///< probability that this step moves the chain, given its
                            ///< proposals: a for Metropolis and MTM, Σf(y)/(f(x)+Σf(y)) for bundle
  std::uint32_t chosen = 0;          ///< index of the new state: 0 = stayed at x, l+1 = candidate y_l
  std::uint32_t evaluations = 0;     ///< target evaluations (new points traced)
  std::uint32_t zero_values = 0;     ///< evaluations with f* = 0 (including invalid ones)
  std::uint32_t invalid_values = 0;  ///< evaluations that returned NaN, ±Inf or < 0 (treated as 0)
  std::uint32_t splats = 0;          ///< splat callbacks made (weights > 0 only)
  double splatted_weight = 0.0;      ///< sum of splat weights; 1 up to rounding for every kernel
};

/// Acceptance record of one mutation type over a chain (or many chains, via merge).
struct ChainStats {
  std::uint64_t steps = 0;
  std::uint64_t moved = 0;
  std::uint64_t evaluations = 0;
  std::uint64_t zero_values = 0;
  std::uint64_t invalid_values = 0;
  std::uint64_t splats = 0;
  double acceptance_sum = 0.0;  ///< Σ acceptance probability (lower variance than `moved`)

  void record(const StepResult& r) {
    ++steps;
    moved += r.moved ? 1u : 0u;
    evaluations += r.evaluations;
    zero_values += r.zero_values;
    invalid_values += r.invalid_values;
    splats += r.splats;
    acceptance_sum += r.acceptance;
  }

  void merge(const ChainStats& o) {
    steps += o.steps;
    moved += o.moved;
    evaluations += o.evaluations;
    zero_values += o.zero_values;
    invalid_values += o.invalid_values;
    splats += o.splats;
    acceptance_sum += o.acceptance_sum;
  }

  /// Fraction of steps that moved the chain (0 when no steps were taken).
  double acceptance_rate() const { return steps ? double(moved) / double(steps) : 0.0; }
  /// Mean acceptance probability (0 when no steps were taken).
  double mean_acceptance() const { return steps ? acceptance_sum / double(steps) : 0.0; }
};

/// One ChainStats per MutationKind.
struct KernelStats {
  std::array<ChainStats, k_mutation_kind_count> per_kind{};

  void record(const StepResult& r) { (*this)[r.kind].record(r); }
  ChainStats& operator[](MutationKind k) { return per_kind[static_cast<std::size_t>(k)]; }
  const ChainStats& operator[](MutationKind k) const { return per_kind[static_cast<std::size_t>(k)]; }

  void merge(const KernelStats& o) {
    for (std::size_t i = 0; i < k_mutation_kind_count; ++i) per_kind[i].merge(o.per_kind[i]);
  }

  /// Write a JSON object keyed by mutation name, listing only kinds with steps, e.g.
  /// {"mtm": {"steps": 10, "moved": 4, "acceptance_rate": 0.4, ...}}.
  void write_json(std::ostream& os) const {
    os << '{';
    bool first = true;
    for (std::size_t i = 0; i < k_mutation_kind_count; ++i) {
      const ChainStats& s = per_kind[i];
      if (s.steps == 0) continue;
      if (!first) os << ", ";
      first = false;
      os << '"' << mutation_kind_name(static_cast<MutationKind>(i)) << "\": {"
         << "\"steps\": " << s.steps << ", \"moved\": " << s.moved
         << ", \"acceptance_rate\": " << s.acceptance_rate()
         << ", \"mean_acceptance\": " << s.mean_acceptance()
         << ", \"evaluations\": " << s.evaluations << ", \"zero_values\": " << s.zero_values
         << ", \"invalid_values\": " << s.invalid_values << ", \"splats\": " << s.splats << '}';
    }
    os << '}';
  }
};

}  // namespace cmlt::mcmc
