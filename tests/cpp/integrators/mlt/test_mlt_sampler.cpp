// MltSampler (integrators/mlt/mlt_sampler.h): bit-exact reject, the distribution of the
// lazy catch-up of n small steps (KS against the wrapped normal with σ√n), uniform large
// steps (chi-square), stream independence, determinism of the keyed numbers.
//
// Statistical checks use fixed keys, so each either always passes or always fails; the
// stated level is the false-alarm rate over the choice of seed. Each also shows power:
// the same statistic rejects a plausible wrong answer.
#include "chi2.h"

#include "integrators/mlt/mlt_sampler.h"

#include <map>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

using namespace cmlt;
using namespace cmlt::mlt;

namespace {

/// CDF of the wrapped normal N(0, s²) mod 1, on the centred interval (-1/2, 1/2].
double wrapped_normal_cdf(double d, double s) {
    auto phi = [](double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); };
    double F = 0.0;
    for (int m = -6; m <= 6; ++m) F += phi((d + m) / s) - phi((-0.5 + m) / s);
    return F;
}

/// Kolmogorov–Smirnov statistic √n·D of sorted samples against a CDF.
template <class Cdf>
double ks_statistic(std::vector<double> x, Cdf cdf) {
    std::sort(x.begin(), x.end());
    const double n = double(x.size());
    double D = 0.0;
    for (size_t i = 0; i < x.size(); ++i) {
        const double F = cdf(x[i]);
        D = std::max(D, std::max(F - double(i) / n, double(i + 1) / n - F));
    }
    return std::sqrt(n) * D;
}

/// KS critical value of √n·D at level 1e-3 (asymptotic Kolmogorov distribution).
constexpr double k_ks_critical_1e3 = 1.949;

/// Centred difference on the torus, in (-1/2, 1/2].
double torus_diff(double a, double b) {
    double d = a - b;
    d -= std::floor(d + 0.5);
    return d;
}

bool same_bits(const std::vector<MltSampler::PrimarySample>& a,
               const std::vector<MltSampler::PrimarySample>& b, size_t n) {
    for (size_t i = 0; i < n; ++i) {
        if (std::memcmp(&a[i].value, &b[i].value, sizeof(double)) != 0) return false;
        if (a[i].last_modified != b[i].last_modified) return false;
    }
    return true;
}

}  // namespace

TEST(MltSampler, RejectRestoresPrimarySamplesBitExactly) {
    MltSampler s(7, 0.05, 0.3, RngDomain::test, 1);
    // a history of accepted and rejected steps of both kinds, reading varying dimensions
    for (int it = 0; it < 200; ++it) {
        s.start_iteration();
        for (uint32_t d = 0; d < uint32_t(3 + it % 7); ++d) s.get2d();
        s.start_stream(MltSampler::light);
        for (uint32_t d = 0; d < uint32_t(it % 3); ++d) s.get1d();
        (it % 3 == 0) ? s.reject() : s.accept();
    }
    for (int trial = 0; trial < 50; ++trial) {
        const auto before = s.samples();
        const int64_t iteration = s.iteration();
        const bool large = s.start_iteration();
        // read every stored dimension and some new ones (sometimes twice)
        for (uint32_t d = 0; d < 12; ++d) s.get2d();
        s.set_dimension(2);
        s.get1d();
        s.start_stream(MltSampler::connection);
        for (uint32_t d = 0; d < 5; ++d) s.get1d();
        s.reject();
        EXPECT_EQ(s.iteration(), iteration);
        ASSERT_GE(s.samples().size(), before.size());
        EXPECT_TRUE(same_bits(s.samples(), before, before.size()))
            << "trial " << trial << (large ? " (large step)" : " (small step)");
        // the proposal did change the samples (otherwise the test proves nothing)
        s.start_iteration(large);
        for (uint32_t d = 0; d < 12; ++d) s.get2d();
        EXPECT_FALSE(same_bits(s.samples(), before, before.size()));
        s.reject();
        EXPECT_TRUE(same_bits(s.samples(), before, before.size()));
        if (trial % 2) {  // move on
            s.start_iteration();
            for (uint32_t d = 0; d < 6; ++d) s.get2d();
            s.accept();
        }
    }
}

TEST(MltSampler, ReadingTwiceInOneProposalGivesTheSameValue) {
    MltSampler s(3, 0.1, 0.0, RngDomain::test, 2);
    s.start_iteration(false);
    const double a = s.sample(5);
    s.accept();
    s.start_iteration(false);
    const double b1 = s.sample(5), b2 = s.sample(5);
    EXPECT_EQ(b1, b2);
    EXPECT_NE(a, b1);
    s.reject();
    s.start_iteration(false);
    s.reject();
    EXPECT_EQ(s.samples()[5].value, a);
}

TEST(MltSampler, LazyCatchUpOfNSmallStepsIsWrappedNormalSigmaSqrtN) {
    // Read sample A, accept n steps that never read A (each reads B), then read A: the
    // catch-up must be one wrapped N(0, n σ²) step. σ√n = 0.2 makes wrapping matter.
    const double sigma = 0.05;
    const int n = 16;
    const int chains = 20000;
    std::vector<double> diff;
    diff.reserve(chains);
    for (int c = 0; c < chains; ++c) {
        MltSampler s(11, sigma, 0.0, RngDomain::test, uint32_t(c));
        s.start_iteration(false);
        const double a0 = s.sample(0);
        s.accept();
        for (int k = 0; k < n - 1; ++k) {
            s.start_iteration(false);
            s.sample(1);
            s.accept();
        }
        // rejected proposals in between must not count as steps
        for (int k = 0; k < 3; ++k) {
            s.start_iteration(false);
            s.sample(0);
            s.sample(1);
            s.reject();
        }
        s.start_iteration(false);
        diff.push_back(torus_diff(s.sample(0), a0));
        s.accept();
    }
    const double ks = ks_statistic(diff, [&](double d) { return wrapped_normal_cdf(d, sigma * std::sqrt(double(n))); });
    EXPECT_LT(ks, k_ks_critical_1e3) << "catch-up is not N(0, n sigma^2) wrapped";
    // power: the same data reject a catch-up that counted the 3 rejected steps (n+3),
    // missed 4 steps (n-4), or applied a single σ step
    for (double wrong : {sigma * std::sqrt(double(n + 3)), sigma * std::sqrt(double(n - 4)), sigma}) {
        const double ks_wrong = ks_statistic(diff, [&](double d) { return wrapped_normal_cdf(d, wrong); });
        EXPECT_GT(ks_wrong, k_ks_critical_1e3) << "KS has no power against sigma " << wrong;
    }
}

TEST(MltSampler, CatchUpAfterALargeStepIsFreshUniform) {
    // A, accepted large step that does not read A, then small steps: A must be uniform
    // and independent of its old value (chi-square on the 2-D histogram (old, new)).
    const int bins = 10, chains = 40000;
    std::vector<double> obs(bins * bins, 0.0), exp(bins * bins, double(chains) / (bins * bins));
    for (int c = 0; c < chains; ++c) {
        MltSampler s(5, 0.01, 0.0, RngDomain::test, uint32_t(c));
        s.start_iteration(false);
        const double a0 = s.sample(0);
        s.accept();
        s.start_iteration(true);
        s.sample(1);
        s.accept();
        s.start_iteration(false);
        s.sample(1);
        s.accept();
        s.start_iteration(false);
        const double a1 = s.sample(0);
        obs[size_t(int(a0 * bins) * bins + int(a1 * bins))] += 1;
    }
    const auto r = test::chi2_test(obs, exp);
    EXPECT_TRUE(r.passed(1e-3)) << r.message;
}

TEST(MltSampler, LargeStepsAreUniform) {
    const int bins = 64;
    std::vector<double> obs(bins, 0.0);
    size_t n = 0;
    for (int c = 0; c < 200; ++c) {
        MltSampler s(9, 0.01, 1.0, RngDomain::test, uint32_t(c));
        for (int it = 0; it < 100; ++it) {
            EXPECT_TRUE(s.start_iteration());
            for (int d = 0; d < 4; ++d) {
                const Vec2 u = s.get2d();
                ASSERT_TRUE(u.x >= 0.f && u.x < 1.f && u.y >= 0.f && u.y < 1.f);
                obs[size_t(u.x * bins)] += 1;
                obs[size_t(u.y * bins)] += 1;
                n += 2;
            }
            (it % 2) ? s.accept() : s.reject();
        }
    }
    std::vector<double> exp(bins, double(n) / bins);
    const auto r = test::chi2_test(obs, exp);
    EXPECT_TRUE(r.passed(1e-3)) << r.message;
    // power: a linear tilt of ±5% across [0, 1) is detected in the same counts
    std::vector<double> tilted(bins);
    for (int i = 0; i < bins; ++i) tilted[i] = exp[i] * (1.0 + 0.1 * (double(i) / bins - 0.5));
    EXPECT_FALSE(test::chi2_test(obs, tilted).passed(1e-3));
}

TEST(MltSampler, LargeStepProbabilityIsHonoured) {
    MltSampler s(1, 0.01, 0.3, RngDomain::test, 0);
    int large = 0;
    const int n = 100000;
    for (int i = 0; i < n; ++i) {
        large += s.start_iteration() ? 1 : 0;
        s.get1d();
        (i % 2) ? s.accept() : s.reject();
    }
    // binomial sd = sqrt(n p (1-p)) ≈ 145: 5 sd
    EXPECT_NEAR(large, 0.3 * n, 5 * std::sqrt(n * 0.21));
}

TEST(MltSampler, StreamsAreDisjointAndIndependent) {
    // disjoint index spaces
    for (uint32_t slot = 0; slot < 100; ++slot)
        for (uint32_t k = 0; k < MltSampler::k_stream_count; ++k)
            for (uint32_t k2 = 0; k2 < MltSampler::k_stream_count; ++k2)
                if (k != k2) { EXPECT_NE(MltSampler::index(k, slot), MltSampler::index(k2, slot)); }
    // reading more or fewer light-stream dimensions never changes the camera stream
    MltSampler a(21, 0.02, 0.3, RngDomain::test, 5), b(21, 0.02, 0.3, RngDomain::test, 5);
    for (int it = 0; it < 300; ++it) {
        const bool la = a.start_iteration(), lb = b.start_iteration();
        ASSERT_EQ(la, lb);
        b.start_stream(MltSampler::light);
        for (int d = 0; d < it % 9; ++d) b.get2d();
        a.start_stream(MltSampler::camera);
        b.start_stream(MltSampler::camera);
        for (int d = 0; d < 6; ++d) {
            const Vec2 ua = a.get2d(), ub = b.get2d();
            ASSERT_EQ(ua.x, ub.x);
            ASSERT_EQ(ua.y, ub.y);
        }
        a.start_stream(MltSampler::light);
        for (int d = 0; d < (it * 7) % 5; ++d) a.get1d();
        if (it % 4 == 3) {
            a.reject();
            b.reject();
        } else {
            a.accept();
            b.accept();
        }
    }
    // camera and light values of the same slot are independent: 2-D chi-square
    const int bins = 8, n = 32000;
    std::vector<double> obs(bins * bins, 0.0), exp(bins * bins, double(n) / (bins * bins));
    for (int c = 0; c < n; ++c) {
        MltSampler s(4, 0.01, 0.3, RngDomain::test, uint32_t(c));
        s.start_iteration(true);
        const float cam = s.get1d();
        s.start_stream(MltSampler::light);
        const float light = s.get1d();
        obs[size_t(int(cam * bins) * bins + int(light * bins))] += 1;
    }
    const auto r = test::chi2_test(obs, exp);
    EXPECT_TRUE(r.passed(1e-3)) << r.message;
}

TEST(MltSampler, NumbersDependOnlyOnTheKey) {
    // Same (seed, domain, id) → same chain; another id, domain or seed → different.
    auto run = [](uint64_t seed, RngDomain dom, uint32_t id) {
        MltSampler s(seed, 0.05, 0.3, dom, id);
        std::vector<float> v;
        for (int it = 0; it < 50; ++it) {
            s.start_iteration();
            for (int d = 0; d < 5; ++d) v.push_back(s.get1d());
            (s.uniform() < 0.5) ? s.accept() : s.reject();
        }
        return v;
    };
    const auto a = run(1, RngDomain::chain, 3);
    EXPECT_EQ(a, run(1, RngDomain::chain, 3));
    EXPECT_NE(a, run(1, RngDomain::chain, 4));
    EXPECT_NE(a, run(1, RngDomain::bootstrap, 3));
    EXPECT_NE(a, run(2, RngDomain::chain, 3));
}

TEST(MltSampler, LuminanceWeightsAreACEScg) {
    EXPECT_NEAR(k_luminance_weights[0] + k_luminance_weights[1] + k_luminance_weights[2], 1.0, 1e-6);
    EXPECT_DOUBLE_EQ(target_luminance(Spectrum(1.f)), k_luminance_weights[0] + k_luminance_weights[1] +
                                                          k_luminance_weights[2]);
    EXPECT_EQ(target_luminance(Spectrum(std::nanf(""), 1.f, 1.f)), 0.0);
    EXPECT_EQ(target_luminance(Spectrum(-1.f, 0.f, 0.f)), 0.0);
    EXPECT_EQ(target_luminance(Spectrum(INFINITY, 0.f, 0.f)), 0.0);
}

// ---- multiplexed MLT: technique samples, state export / import ----------------------

#include "integrators/mlt/chain_state.h"
#include "integrators/mlt/technique.h"

namespace {

/// A toy "path": reads a data-dependent number of samples from the three streams (the
/// technique first, as PssmltTracer does) and returns a value of them all.
double toy_path(MltSampler& s) {
    s.start_stream(MltSampler::connection);
    const Vec2 t = s.get2d();
    s.start_stream(MltSampler::camera);
    double v = s.get2d().x;
    const int n = 1 + int(t.x * 4.f);
    for (int i = 0; i < n; ++i) v += 0.5 * s.get1d();
    s.start_stream(MltSampler::light);
    v += s.get2d().y;
    return v + t.y;
}

}  // namespace

TEST(MltSampler, FrozenTechniqueSlotsChangeOnlyAtLargeSteps) {
    MltSampler s(9, 0.05, 0.0);
    s.freeze_in_small_steps(MltSampler::connection, 2);
    s.start_iteration(true);
    toy_path(s);
    s.accept();
    const double t0 = s.sample(MltSampler::index(MltSampler::connection, 0));
    const double t1 = s.sample(MltSampler::index(MltSampler::connection, 1));
    int camera_moved = 0;
    for (int k = 0; k < 200; ++k) {
        const double c_before = s.samples()[MltSampler::index(MltSampler::camera, 0)].value;
        s.start_iteration(false);
        toy_path(s);
        EXPECT_EQ(s.sample(MltSampler::index(MltSampler::connection, 0)), t0);
        EXPECT_EQ(s.sample(MltSampler::index(MltSampler::connection, 1)), t1);
        camera_moved += s.sample(MltSampler::index(MltSampler::camera, 0)) != c_before;
        if (k % 3) s.accept(); else s.reject();
    }
    EXPECT_EQ(camera_moved, 200);  // other coordinates do move
    s.start_iteration(true);
    toy_path(s);
    EXPECT_NE(s.sample(MltSampler::index(MltSampler::connection, 0)), t0);
}

TEST(MltSampler, ExportedStateReplaysToTheSamePath) {
    MltSampler s(3, 0.02, 0.3);
    s.start_iteration(true);
    double fx = toy_path(s);
    s.accept();
    for (int k = 0; k < 300; ++k) {
        s.start_iteration();
        const double fy = toy_path(s);
        if (s.uniform() < 0.5) {
            s.accept();
            fx = fy;
        } else {
            s.reject();
        }
    }
    const auto u = s.current_state();
    // round trip through float (ChainState) and bytes
    ChainStates states;
    ChainState c;
    c.chain_id = 77;
    for (size_t k = 0; k < 3; ++k) c.u[k].assign(u[k].begin(), u[k].end());
    states.chains.push_back(c);
    const ChainStates back = ChainStates::from_bytes(states.to_bytes());
    ASSERT_EQ(back.chains.size(), 1u);
    EXPECT_EQ(back.chains[0].chain_id, 77u);
    EXPECT_EQ(back.to_bytes(), states.to_bytes());
    EXPECT_THROW(ChainStates::from_bytes(states.to_bytes().substr(0, 20)), std::invalid_argument);

    MltSampler t(11, 0.02, 0.3);  // another key: only the imported values matter
    t.import_state(back.chains[0].u);
    t.begin_replay();
    const double f_import = toy_path(t);
    t.end_replay();
    EXPECT_EQ(f_import, fx);
    // the replay did not mutate anything the path read, and the imported state exports
    // the same values again (read coordinates only)
    const auto u2 = t.current_state();
    for (size_t k = 0; k < 3; ++k)
        for (size_t i = 0; i < std::min(u[k].size(), u2[k].size()); ++i)
            if (!std::isnan(u[k][i])) { EXPECT_EQ(float(u[k][i]), float(u2[k][i])); }
    // and the chain goes on: small steps from the imported state
    t.start_iteration(false);
    toy_path(t);
    t.reject();
    t.begin_replay();
    EXPECT_EQ(toy_path(t), fx);
    t.end_replay();
}

TEST(Technique, DepthPmfSumsToOneAndInverseCdfMatches) {
    for (int max_depth : {1, 5, 64}) {
        TechniqueSampler ts(max_depth);
        double sum = 0;
        for (int d = 0; d <= max_depth; ++d) {
            EXPECT_GT(ts.depth_pmf(d), 0.0);
            sum += ts.depth_pmf(d);
        }
        EXPECT_NEAR(sum, 1.0, 1e-12);
        // chi-square of depths from a regular grid of u: exact up to the grid
        std::vector<double> count(size_t(max_depth) + 1, 0.0);
        const int n = 1 << 20;
        for (int i = 0; i < n; ++i) count[size_t(ts.depth((i + 0.5) / n))] += 1;
        for (int d = 0; d <= max_depth; ++d)
            EXPECT_NEAR(count[size_t(d)] / n, ts.depth_pmf(d), 2.0 / n) << d;
        // choose(): pmf = p(depth) p(s,t | depth); every (s, t) valid
        int depth, s, t;
        const double p = ts.choose(0.999f, 0.5f, &depth, &s, &t);
        EXPECT_EQ(s + t, depth + 2);
        EXPECT_NEAR(p, ts.depth_pmf(depth) / BdptTracer::strategy_count(depth), 1e-12);
    }
}

TEST(Technique, CameraTechniqueSharesEveryPathTracerStrategyByItsEffectivePmf) {
    // With q > 0, u0 < q picks the camera technique; the rest is the multiplexed pmf
    // scaled by 1 - q. Over a regular grid of (u0, u1): the camera technique's share is
    // q, each strategy's share (1 - q) p(d) p(s, t | d), choose() returns p_eff (q added
    // for s <= 1) and the camera weights are 1 / p_eff: so every s <= 1 strategy is
    // counted once in expectation, E = q w + (1 - q) p w = 1 with w = 1 / p_eff.
    for (int min_depth : {0, 2}) {
        const int max_depth = 6;
        const double q = 0.35;
        TechniqueSampler ts(max_depth, min_depth, q);
        TechniqueSampler plain(max_depth, min_depth);
        EXPECT_EQ(ts.camera_probability(), q);
        const int n0 = 1 << 12, n1 = 1 << 8;
        double camera = 0;
        std::map<std::pair<int, int>, double> share;
        for (int i = 0; i < n0; ++i)
            for (int j = 0; j < n1; ++j) {
                int depth, s, t;
                const double p = ts.choose(float((i + 0.5) / n0), float((j + 0.5) / n1), &depth, &s, &t);
                if (depth < 0) {
                    EXPECT_EQ(p, 1.0);
                    camera += 1;
                    continue;
                }
                EXPECT_EQ(s + t, depth + 2);
                EXPECT_GE(depth, min_depth);
                EXPECT_NEAR(p, ts.strategy_pmf(depth, s), 1e-15);
                share[{depth, s}] += 1;
            }
        const double n = double(n0) * n1;
        EXPECT_NEAR(camera / n, q, 1.0 / n0);
        const auto& w = ts.camera_weights();
        ASSERT_EQ(w.size(), size_t(2 * (max_depth + 1)));
        for (int d = 0; d <= max_depth; ++d)
            for (int s = 0; s <= d + 1; ++s) {
                if (d == 0 && s == 1) continue;  // (1, 1): no strategy
                const double own = (1.0 - q) * plain.depth_pmf(d) / BdptTracer::strategy_count(d);
                const double measured = share.count({d, s}) ? share[{d, s}] / n : 0.0;
                EXPECT_NEAR(measured, own, 2.0 / n0 + 2.0 / n1) << d << " " << s;
                if (s > 1) {
                    EXPECT_NEAR(ts.strategy_pmf(d, s), own, 1e-15);
                    continue;
                }
                if (d < min_depth) {
                    EXPECT_EQ(w[size_t(2 * d + s)], 0.f) << d;
                    continue;
                }
                // one unit of C_st per strategy in expectation over the two techniques
                EXPECT_NEAR(q * w[size_t(2 * d + s)] + own / ts.strategy_pmf(d, s), 1.0, 1e-6) << d << " " << s;
            }
        EXPECT_EQ(w[1], 0.f);  // (1, 1)
    }
    // q = 0: the multiplexed sampler as before, bit for bit
    TechniqueSampler a(64, 2), b(64, 2, 0.0);
    for (float u0 : {0.f, 0.3f, 0.77f, 0.999f})
        for (float u1 : {0.f, 0.5f, 0.99f}) {
            int d1, s1, t1, d2, s2, t2;
            EXPECT_EQ(a.choose(u0, u1, &d1, &s1, &t1), b.choose(u0, u1, &d2, &s2, &t2));
            EXPECT_EQ(d1, d2);
            EXPECT_EQ(s1, s2);
        }
    EXPECT_TRUE(b.camera_weights().empty());
}
