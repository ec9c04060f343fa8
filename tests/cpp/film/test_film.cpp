// Film: Welford mean/variance in double; non-finite samples counted and dropped.
#include "film/film.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

using namespace cmlt;

TEST(Film, MeanAndVarianceOfTheMean) {
    Film film(2, 1);
    double vals[] = {1, 2, 4, 8};
    for (int i = 0; i < 4; ++i) film.add_sample(1, 0, i, Spectrum(float(vals[i]), 0.f, 1.f));
    std::vector<float> img(6), var(6);
    film.develop(img.data(), var.data());
    double mean = 15.0 / 4, ss = 0;
    for (double v : vals) ss += (v - mean) * (v - mean);
    EXPECT_FLOAT_EQ(img[3], float(mean));
    EXPECT_FLOAT_EQ(var[3], float(ss / 3 / 4));
    EXPECT_FLOAT_EQ(img[5], 1.f);
    EXPECT_FLOAT_EQ(var[5], 0.f);
    EXPECT_EQ(img[0], 0.f);  // untouched pixel
}

TEST(Film, NonFiniteSamplesAreCountedAndDropped) {
    Film film(4, 4);
    float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
    EXPECT_TRUE(film.add_sample(2, 1, 0, Spectrum(1.f)));
    EXPECT_FALSE(film.add_sample(2, 1, 1, Spectrum(nan, 0.f, 0.f)));
    EXPECT_FALSE(film.add_sample(3, 3, 0, Spectrum(0.f, inf, 0.f)));
    EXPECT_FALSE(film.add_sample(1, 1, 7, Spectrum(0.f, 0.f, -inf)));
    EXPECT_TRUE(film.add_sample(2, 1, 2, Spectrum(3.f)));
    EXPECT_EQ(film.nan_samples(), 3u);
    int x, y;
    uint32_t s;
    ASSERT_TRUE(film.first_nan(&x, &y, &s));
    EXPECT_EQ(x, 1);  // first in (pixel, sample) order, not arrival order
    EXPECT_EQ(y, 1);
    EXPECT_EQ(s, 7u);
    std::vector<float> img(48), var(48);
    film.develop(img.data(), var.data());
    for (float v : img) EXPECT_TRUE(std::isfinite(v));
    EXPECT_FLOAT_EQ(img[(1 * 4 + 2) * 3], 2.f);
}

TEST(Film, VarianceFromBlocksOfSamples) {
    // blocks of 4 sample indices: the variance of the mean is the spread of the blocks'
    // means over their count; the mean is the samples' (bit for bit the film without
    // blocks); an unfinished block counts in the mean only
    Film blocks(1, 1), plain(1, 1);
    blocks.set_variance_block(4);
    const double vals[] = {1, 2, 4, 8, 3, 3, 3, 3, 0, 1, 0, 1, 5, 7};  // 3 blocks + 2
    for (uint32_t i = 0; i < 14; ++i) {
        const Spectrum L(float(vals[i]), 1.f, 0.5f * float(i));
        blocks.add_sample(0, 0, i, L);
        plain.add_sample(0, 0, i, L);
    }
    std::vector<float> bi(3), bv(3), pi(3), pv(3);
    blocks.develop(bi.data(), bv.data());
    plain.develop(pi.data(), pv.data());
    for (int c = 0; c < 3; ++c) EXPECT_EQ(bi[c], pi[c]) << c;
    const double m[3] = {15.0 / 4, 12.0 / 4, 2.0 / 4};
    const double mm = (m[0] + m[1] + m[2]) / 3;
    double ss = 0;
    for (double v : m) ss += (v - mm) * (v - mm);
    EXPECT_FLOAT_EQ(bv[0], float(ss / 2 / 3));
    EXPECT_EQ(bv[1], 0.f);  // every block mean 1
    // channel 2 (0.5 i): block means 0.75, 2.75, 4.75
    EXPECT_FLOAT_EQ(bv[2], float((4.0 + 0.0 + 4.0) / 2 / 3));
    EXPECT_NE(bv[0], pv[0]);
}

TEST(Film, BlockWeightsAreTheSamplesWeights) {
    // weighted samples (a filter's): a block's mean is its weighted mean and its weight
    // the sum of its samples' weights; one block: no variance yet
    Film film(1, 1);
    film.set_variance_block(2);
    film.add_sample(0, 0, 0, Spectrum(2.f), 1.f);
    film.add_sample(0, 0, 1, Spectrum(4.f), 3.f);  // block 0: mean 3.5, weight 4
    std::vector<float> img(3), var(3);
    film.develop(img.data(), var.data());
    EXPECT_FLOAT_EQ(img[0], 3.5f);
    EXPECT_EQ(var[0], 0.f);
    // a complete last block counts at once (no sample of the next one needed)
    Film two(1, 1);
    two.set_variance_block(2);
    for (uint32_t i = 0; i < 4; ++i) two.add_sample(0, 0, i, Spectrum(i < 2 ? 1.f : 3.f));
    two.develop(img.data(), var.data());
    EXPECT_FLOAT_EQ(var[0], float((1.0 + 1.0) / 1 / 2));  // block means 1, 3
    film.add_sample(0, 0, 2, Spectrum(1.f), 2.f);
    film.add_sample(0, 0, 3, Spectrum(1.f), 2.f);  // block 1: mean 1, weight 4
    film.add_sample(0, 0, 4, Spectrum(9.f), 1.f);  // block 2 unfinished
    film.develop(img.data(), var.data());
    EXPECT_FLOAT_EQ(img[0], float((2.0 + 12.0 + 4.0 + 9.0) / 9.0));
    // weighted Welford over the two finished blocks: m2 = Σ W (Y - Ȳ)^2, var = m2 / ((n - 1) Σ W)
    const double ybar = (4 * 3.5 + 4 * 1.0) / 8;
    const double m2 = 4 * (3.5 - ybar) * (3.5 - ybar) + 4 * (1.0 - ybar) * (1.0 - ybar);
    EXPECT_FLOAT_EQ(var[0], float(m2 / (1 * 8)));
}

TEST(Film, TrimmedMeanLeavesOutTheLargestAndSmallestPass) {
    // the relMSE estimate's denominator (error_target.h): each pixel's weighted mean
    // without its largest and its smallest pass (by the channels' sum), NaN where it has
    // fewer than three; equal passes are two different ones
    Film film(4, 1);
    const float vals[] = {1, 2, 40, 3, 0.5f};  // pixel 0: a firefly (40) and the smallest (0.5)
    const float w[] = {1, 2, 1, 1, 4};
    for (uint32_t i = 0; i < 5; ++i) film.add_sample(0, 0, i, Spectrum(vals[i], 2.f * vals[i], 1.f), w[i]);
    film.add_sample(1, 0, 0, Spectrum(5.f));  // two passes: none
    film.add_sample(1, 0, 1, Spectrum(7.f));
    for (uint32_t i = 0; i < 4; ++i) film.add_sample(2, 0, i, Spectrum(3.f));  // all equal
    std::vector<float> img(12), var(12), rob(12);
    film.develop(img.data(), var.data(), rob.data());
    // without 40 (weight 1) and 0.5 (weight 4): (1 * 1 + 2 * 2 + 3 * 1) / 4
    EXPECT_FLOAT_EQ(rob[0], 2.f);
    EXPECT_FLOAT_EQ(rob[1], 4.f);
    EXPECT_FLOAT_EQ(rob[2], 1.f);  // the channel of 1s: 1 whatever is left out
    EXPECT_TRUE(std::isnan(rob[3]));
    EXPECT_FLOAT_EQ(img[3], 6.f);
    EXPECT_FLOAT_EQ(rob[6], 3.f);
    EXPECT_TRUE(std::isnan(rob[9]));  // an untouched pixel
    // the mean and variance are as without it
    std::vector<float> img2(12), var2(12);
    film.develop(img2.data(), var2.data());
    for (int i = 0; i < 12; ++i) {
        EXPECT_EQ(img[i], img2[i]);
        EXPECT_EQ(var[i], var2[i]);
    }
}

TEST(Film, TrimmedMeanOfBlocks) {
    // with blocks: the finished blocks' mean without the largest and the smallest block
    Film film(1, 1);
    film.set_variance_block(2);
    const float vals[] = {1, 3, 10, 30, 2, 2, 0, 0, 4, 4};  // block means 2, 20, 2, 0, 4
    for (uint32_t i = 0; i < 10; ++i) film.add_sample(0, 0, i, Spectrum(vals[i]));
    std::vector<float> img(3), var(3), rob(3);
    film.develop(img.data(), var.data(), rob.data());
    EXPECT_FLOAT_EQ(rob[0], (2.f + 2.f + 4.f) / 3.f);
    EXPECT_FLOAT_EQ(img[0], 5.6f);
}
