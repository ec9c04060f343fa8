#pragma once
// Per-channel image statistics for the integrator-agreement tests (test_bdpt.cpp,
// test_cylinder_shaping.cpp, test_furnace.cpp).
//
// The film's variance AOV holds, per pixel and channel, the variance of that pixel's mean
// over its passes (independent). The pixels of a PT render are independent, so the
// variance of a per-channel mean over pixels (a block, the whole image) is the sum of the
// pixel variances over n^2. The channels of one pixel are NOT independent: R, G and B of
// one path are strongly correlated, and the old all-channels mean with the
// channels-independent standard error had a true variance 2.3-3.7 x the estimate
// (measured over 64 seeds: Cornell box 2.5 (PT) / 2.3 (BDPT), glass caustic 3.5, dome +
// sun 3.7 (PT) / 3.1 (BDPT), sphere light 3.5). So every statistic here is per channel.
//
// BDPT: the light-tracing splats of one pass add a light subpath's contributions to
// several pixels, which correlates the pixels of a pass a little. Measured over 64
// seeds, true / estimated variance of the per-channel image means: 0.77-0.80 (Cornell),
// 1.19 (glass caustic), 1.01-1.11 (dome + sun), 1.19-1.21 (sphere light), PT 0.84-1.33;
// per-channel 8x8 blocks 0.97-1.05 on average; the sampling sd of each ratio is 0.18.
// The per-channel variance AOV is used as is — times RenderStats::pixel_correlation where
// a wide filter splats every camera sample to its neighbours (film/pass_splatter.h): a
// sum over many neighbouring pixels then has about that times the sum of their variances
// (each sample counted once in the sum but spread over ~1/∫f² pixels' variances).
#include "integrators/common/render.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace cmlt::test {

/// Two-sided z for a per-comparison level alpha: erfc(z / sqrt 2) = alpha.
inline double z_for(double alpha) {
    double lo = 0, hi = 40;
    for (int i = 0; i < 200; ++i) {
        double mid = 0.5 * (lo + hi);
        if (std::erfc(mid / std::sqrt(2.0)) > alpha) lo = mid; else hi = mid;
    }
    return lo;
}

/// Per-channel means of bs x bs pixel blocks and the variances of those means; index
/// (block row * blocks per row + block column) * 3 + channel. bs = 0: the whole image.
struct BlockStats {
    int count = 0;  ///< blocks
    std::vector<double> mean, var;
};
inline BlockStats block_stats(const RenderResult& r, int bs) {
    int bx = bs > 0 ? bs : r.width, by = bs > 0 ? bs : r.height;
    int bw = r.width / bx, bh = r.height / by;
    BlockStats b;
    b.count = bw * bh;
    b.mean.assign(size_t(bw * bh * 3), 0.0);
    b.var.assign(size_t(bw * bh * 3), 0.0);
    const double n = double(bx) * by;
    const double corr = r.stats.pixel_correlation;
    for (int y = 0; y < bh * by; ++y)
        for (int x = 0; x < bw * bx; ++x)
            for (int c = 0; c < 3; ++c) {
                size_t i = (size_t(y) * r.width + x) * 3 + c;
                size_t k = (size_t(y / by) * bw + x / bx) * 3 + c;
                b.mean[k] += r.image[i] / n;
                b.var[k] += corr * r.variance[i] / (n * n);
            }
    return b;
}

struct AgreementOptions {
    int block = 8;                 ///< block size in pixels
    double alpha_blocks = 1e-3;    ///< family-wise over blocks x channels (Bonferroni)
    double alpha_mean = 1e-4;      ///< family-wise over the three channel means
    double tol_mean = 0.01;        ///< relative tolerance of the image means
    /// Require z se < tol_mean * mean on every lit channel, so that a mean error of
    /// 2 tol_mean is always caught; off for scenes too noisy for that at test budget.
    bool require_resolution = true;
    /// Power of the block test: a relative error `wrong` in a block must be flagged in
    /// more than `min_flagged` of the bright blocks (> 10% of the mean block).
    double wrong = 0.2, min_flagged = 0.5;
};

/// Images a and b estimate the same thing: per-channel block means within their joint
/// confidence intervals (z-test, Bonferroni over blocks and channels, family-wise
/// alpha_blocks), and per channel |mean_a - mean_b| < tol_mean * mean_a + z se (z for
/// alpha_mean / 3). False-alarm rate of one call: alpha_blocks + alpha_mean.
inline void expect_images_agree(const RenderResult& a, const RenderResult& b, const std::string& what,
                                const AgreementOptions& o = AgreementOptions()) {
    BlockStats ba = block_stats(a, o.block), bb = block_stats(b, o.block);
    const double z = z_for(o.alpha_blocks / double(ba.mean.size()));
    double worst = 0, mean_block = 0;
    for (double m : ba.mean) mean_block += m / double(ba.mean.size());
    int bright = 0, flagged = 0;
    for (size_t k = 0; k < ba.mean.size(); ++k) {
        double se = std::sqrt(ba.var[k] + bb.var[k]);
        if (se == 0 && ba.mean[k] == bb.mean[k]) continue;  // black in both, no noise
        double zk = std::fabs(ba.mean[k] - bb.mean[k]) / std::max(se, 1e-300);
        worst = std::max(worst, zk);
        EXPECT_LT(zk, z) << what << ": block " << k / 3 << " channel " << k % 3 << ": "
                         << ba.mean[k] << " vs " << bb.mean[k] << " (joint stderr " << se << ")";
        if (ba.mean[k] > 0.1 * mean_block) {
            ++bright;
            if (std::fabs((1 + o.wrong) * ba.mean[k] - bb.mean[k]) > z * se) ++flagged;
        }
    }
    ASSERT_GT(bright, 0) << what << ": nothing lit";
    double frac = double(flagged) / bright;
    EXPECT_GT(frac, o.min_flagged) << what << ": the block test is too weak to see a "
                                   << o.wrong * 100 << "% error";
    BlockStats ma = block_stats(a, 0), mb = block_stats(b, 0);
    const double zm = z_for(o.alpha_mean / 3);
    double rel[3] = {0, 0, 0}, res[3] = {0, 0, 0};
    for (int c = 0; c < 3; ++c) {
        double se = std::sqrt(ma.var[size_t(c)] + mb.var[size_t(c)]);
        double A = ma.mean[size_t(c)], B = mb.mean[size_t(c)];
        rel[c] = A > 0 ? B / A - 1 : 0;
        res[c] = A > 0 ? zm * se / A : 0;
        EXPECT_LT(std::fabs(A - B), o.tol_mean * A + zm * se)
            << what << ": channel " << c << " mean " << A << " vs " << B << " (joint stderr " << se << ")";
        if (o.require_resolution && A > 0) {
            EXPECT_LT(zm * se, o.tol_mean * A)
                << what << ": channel " << c << " not converged enough for the "
                << o.tol_mean * 100 << "% check";
        }
    }
    std::printf("[%s] means rel. diff %+.4f %+.4f %+.4f (resolution %.4f %.4f %.4f), worst block |z| "
                "%.2f (limit %.2f), %.0f%% of %d bright blocks would flag a %.0f%% error\n",
                what.c_str(), rel[0], rel[1], rel[2], res[0], res[1], res[2], worst, z, 100 * frac,
                bright, 100 * o.wrong);
}

}  // namespace cmlt::test
