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
