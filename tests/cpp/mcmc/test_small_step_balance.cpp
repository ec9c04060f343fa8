// Detailed balance of the small-step mutations on a target whose paths read a variable
// number of primary samples: u0 always, u1 only where u0 >= 1/2 (as Russian roulette, a
// pass-through surface or the pt path sampler read more numbers on some paths):
//   f(u) = 1 for u0 < 1/2;  10 for u0 >= 1/2, u1 < 0.1;  0.1 otherwise,
// so π(u0 < 1/2) = 0.5 / (0.5 + 0.5 (0.1·10 + 0.9·0.1)) = 0.47847 and
// π(u1 < 0.1 | u0 >= 1/2) = 1 / 1.09 = 0.91743.
// Many short chains (20 small steps, σ = 0.1) start from exact draws of π (rejection
// sampling); a kernel that leaves π invariant keeps both probabilities, so their final
// states are binomial draws and each probability is checked by a z-test at |z| < 5
// (false-alarm rate 6e-7 per check for the given seeds).
//
//  * PSSMLT's lazy MltSampler (an unread number is drawn afresh when first read):
//    invariant.
//  * Coherent MLT's small step (integrators/cmlt/perturbations.h): a refresh of the
//    coordinates the current state has not read, then a Gaussian on every coordinate
//    (the unread ones lazily), with metropolis_step, mtm_step (k = 2) and bundle_step:
//    invariant. (Before the refresh the step perturbed only the coordinates the state
//    had materialised and left the others at their key's values, which rejected
//    proposals had read: a proposal reading u1 for the first time saw that fixed value,
//    the reverse move would perturb it, and the chains drifted to π(u0 < 1/2) ≈ 0.52.)
#include "integrators/cmlt/cmlt_state.h"
#include "integrators/cmlt/perturbations.h"
#include "integrators/mlt/mlt_sampler.h"
#include "mcmc/kernels.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>

using namespace cmlt;
using namespace cmlt::mcmc;
using cmlt::mlt::MltSampler;

namespace {

constexpr double k_pi_a = 0.5 / (0.5 + 0.5 * (0.1 * 10.0 + 0.9 * 0.1));
constexpr double k_pi_b = 1.0 / 1.09;
constexpr double k_sigma = 0.1;
constexpr int k_steps = 20;
constexpr uint32_t k_chains = 40000;
constexpr uint64_t k_seed = 20261202;

double toy_f(double u0, bool has_u1, double u1) {
    if (u0 < 0.5) return 1.0;
    EXPECT_TRUE(has_u1);
    return u1 < 0.1 ? 10.0 : 0.1;
}

struct Tally {
    uint64_t n = 0, a = 0, nb = 0, b = 0;
    void add(double u0, double u1) {
        ++n;
        if (u0 < 0.5) {
            ++a;
        } else {
            ++nb;
            if (u1 < 0.1) ++b;
        }
    }
    static double z(uint64_t k, uint64_t n, double p) {
        return (double(k) - double(n) * p) / std::sqrt(double(n) * p * (1.0 - p));
    }
    void check(const char* what) const {
        const double za = z(a, n, k_pi_a), zb = z(b, nb, k_pi_b);
        EXPECT_LT(std::fabs(za), 5.0) << what << ": P(u0 < 1/2) = " << double(a) / double(n) << " over " << n
                                      << " chains, π gives " << k_pi_a << " (z = " << za << ")";
        EXPECT_LT(std::fabs(zb), 5.0) << what << ": P(u1 < 0.1 | u0 >= 1/2) = " << double(b) / double(nb)
                                      << ", π gives " << k_pi_b << " (z = " << zb << ")";
    }
};

// ---- PSSMLT: MltSampler ----------------------------------------------------------------

/// f of the sampler's current proposal; reads u1 only where u0 >= 1/2.
double eval_sampler(MltSampler& s, double* u0, double* u1) {
    s.start_stream(MltSampler::camera);
    *u0 = s.get1d();
    const bool read = *u0 >= 0.5;
    *u1 = read ? s.get1d() : -1.0;
    return toy_f(*u0, read, *u1);
}

TEST(SmallStepBalance, PssmltLazyMutationKeepsAVariableLengthTargetInvariant) {
    Tally t;
    for (uint32_t c = 0; c < k_chains; ++c) {
        MltSampler s(k_seed, k_sigma, 0.0, RngDomain::test, c);
        double u0, u1, fx;
        for (;;) {  // exact start: uniform large steps accepted with f / max f
            s.start_iteration(true);
            fx = eval_sampler(s, &u0, &u1);
            if (s.uniform() < fx / 10.0) {
                s.accept();
                break;
            }
            s.reject();
        }
        for (int k = 0; k < k_steps; ++k) {
            s.start_iteration(false);
            double y0, y1;
            const double fy = eval_sampler(s, &y0, &y1);
            if (s.uniform() < std::min(1.0, fy / fx)) {
                s.accept();
                fx = fy;
                u0 = y0;
                u1 = y1;
            } else {
                s.reject();
            }
        }
        t.add(u0, u1);
    }
    t.check("pssmlt small steps");
}

// ---- coherent MLT: the small-step perturbation of perturbations.h ---------------------------

/// The toy target over a coherent::State (reads through PointSampler, which records the
/// extent the small step perturbs).
struct ToyTarget {
    uint64_t seed;
    double operator()(const coherent::State& s) const {
        s.extent.fill(0);
        coherent::PointSampler p(s, seed);
        p.start_stream(MltSampler::camera);
        const double u0 = p.get1d();
        const bool read = u0 >= 0.5;
        const double u1 = read ? double(p.get1d()) : -1.0;
        return toy_f(u0, read, u1);
    }
};

double coordinate(const coherent::State& s, uint32_t slot) {
    return double(unit_float(s.value(k_seed, MltSampler::index(MltSampler::camera, slot))));
}

enum class Kernel { metropolis, mtm, bundle };

void run_cmlt_small_steps(Kernel kernel) {
    const ToyTarget f{k_seed};
    Tally t;
    for (uint32_t c = 0; c < k_chains; ++c) {
        CounterRng rng(k_seed, RngDomain::test, c);
        coherent::State x;
        double fx = 0.0;
        for (uint64_t p = 1;; ++p) {  // exact start: independent keys accepted with f / max f
            x = coherent::State{};
            x.key = coherent::StateKey{RngDomain::test, c, p};
            fx = f(x);
            if (rng.uniform() < fx / 10.0) break;
        }
        Chain<coherent::State> chain;
        chain.x = x;
        chain.fx = fx;
        Workspace<coherent::State> ws(2, x);
        auto splat = [](const coherent::State&, double) {};
        for (int k = 0; k < k_steps; ++k) {
            // as the integrator: one proposal per inner step (it draws the step's refresh)
            const auto prop = coherent::PerturbationProposal::make(coherent::Perturbation::small_step, k_seed, 1.0,
                                                                   k_sigma, 64, 64, rng);
            if (kernel == Kernel::metropolis) metropolis_step(chain, f, prop, splat, rng, ws);
            else if (kernel == Kernel::mtm) mtm_step(chain, f, prop, splat, rng, ws);
            else bundle_step(chain, f, prop, splat, rng, ws);
        }
        f(chain.x);  // its extent: u1 counts only where the path reads it
        t.add(coordinate(chain.x, 0), coordinate(chain.x, 2));
    }
    t.check(kernel == Kernel::metropolis ? "cmlt small step, metropolis_step"
            : kernel == Kernel::mtm      ? "cmlt small step, mtm_step"
                                         : "cmlt small step, bundle_step");
}

TEST(SmallStepBalance, CmltSmallStepMetropolisKeepsAVariableLengthTargetInvariant) {
    run_cmlt_small_steps(Kernel::metropolis);
}

TEST(SmallStepBalance, CmltSmallStepMtmKeepsAVariableLengthTargetInvariant) {
    run_cmlt_small_steps(Kernel::mtm);
}

TEST(SmallStepBalance, CmltSmallStepBundleKeepsAVariableLengthTargetInvariant) {
    run_cmlt_small_steps(Kernel::bundle);
}

}  // namespace
