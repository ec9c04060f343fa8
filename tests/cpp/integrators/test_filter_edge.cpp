// The filtered edge: an emissive half-plane (radiance 1) against black, its edge a
// vertical line at raster x_e = 12.3 of a 24 x 24 pinhole image, seen directly. Every
// pixel of column j then shows the filtered step F(x_e - c_j), F the integral of the
// filter's 1-D profile (PixelFilter::integral_1d), c_j = j + 1/2 — in every row, the
// border rows included (film positions and light tracing reach the filter's margin
// beyond the image). Each integrator's column means (over the 24 rows) are compared
// with F within z = 4.5 standard errors (pt, bdpt: the rows' spread; pssmlt/cmlt: the
// spread of 64 independent chain groups' column means — a chain's splats are correlated
// over neighbouring rows, so the rows' spread read their error ~1.3x low and 1 in ~30
// seeds missed — with the Student quantile of 63 degrees of freedom in place of z, and
// the normalisation b's relative standard error as a common scale), plus 1e-4 for the
// table weights' rounding: 24 columns x 7 renders at ~7e-6 each, a false-alarm rate
// below 1e-3.
// pssmlt/cmlt render without a direct pass, so that the chains' footprint splats make
// the whole image. The box-filtered render is checked against the box's profile and
// against the gaussian's, which it must miss (the test tells the filters apart).
#include "test_util.h"

#include "film/filter.h"
#include "integrators/common/render.h"

#include <gtest/gtest.h>

#include <cmath>
#include <sstream>
#include <string>

using namespace cmlt;
using namespace cmlt::test;

namespace {

constexpr int k_size = 24;
constexpr double k_edge = 12.3;  // raster x of the edge
constexpr double k_z = 4.5;

void edge_scene(Scene& s) {
    s.set_materials({Material{Spectrum(0.f), Spectrum(1.f)}});
    // the camera sees x in [-1, 1] at z = -1 (focal 18, aperture 36): 2 / 24 per pixel
    const float xe = float(-1.0 + k_edge * 2.0 / k_size);
    s.add_instance(s.add_mesh("/half", quad_mesh(Vec3(0.5f * (xe - 10.f), 0, -1), Vec3(0.5f * (xe + 10.f), 0, 0),
                                                 Vec3(0, 10.f, 0), 0)),
                   Mat4());
    s.set_camera(camera_at(Mat4(), 18.f, 36.f));
}

struct Profile {
    double mean[k_size], se[k_size];
    double z = k_z;  ///< the bound in standard errors (a Student quantile for chain groups)
};

/// The two-sided quantile of Student's t with `dof` degrees of freedom at the normal
/// quantile z (Cornish–Fisher, two terms: within 0.5 % at z = 4.5 for dof >= 30).
double student_quantile(double z, double dof) {
    const double z3 = z * z * z, z5 = z3 * z * z;
    return z + (z3 + z) / (4.0 * dof) + (5.0 * z5 + 16.0 * z3 + 3.0 * z) / (96.0 * dof * dof);
}

constexpr int k_groups = 64;

Profile render_profile(const std::string& integrator, const std::string& filter, int spp) {
    Scene scene;
    edge_scene(scene);
    RenderSettings s;
    s.width = s.height = k_size;
    s.spp = spp;
    s.threads = 2;
    s.seed = 3;
    s.integrator = integrator;
    s.pixel_filter = filter;
    s.direct_fraction = 0.0;
    s.chains = 256;
    s.bootstrap_samples = 20000;
    s.error_groups = k_groups;
    const RenderResult r = render(scene, s);
    EXPECT_EQ(r.stats.pixel_filter, filter);
    const double b_rel = r.stats.mlt.enabled && r.stats.mlt.b > 0 ? r.stats.mlt.b_stderr / r.stats.mlt.b : 0.0;
    Profile p;
    for (int x = 0; x < k_size; ++x) {
        double s1 = 0, s2 = 0;
        for (int y = 0; y < k_size; ++y) {
            const double v = r.image[3 * (size_t(y) * k_size + size_t(x))];  // red = green = blue
            s1 += v;
            s2 += v * v;
        }
        const double m = s1 / k_size, var = std::max(0.0, s2 / k_size - m * m) * k_size / (k_size - 1);
        p.mean[x] = m;
        // the rows of a splatted column share samples (pt, bdpt: film/pass_splatter.h):
        // the mean over many rows has about sqrt(pixel_correlation) (= 1 / ∫ f1²) times
        // the variance the rows' spread says
        p.se[x] = std::sqrt(std::sqrt(r.stats.pixel_correlation) * var / k_size + (b_rel * m) * (b_rel * m));
    }
    if (!r.group_images.empty()) {
        // pssmlt/cmlt: the spread of the groups' column means (each group an unbiased
        // image with the shared b, file comment)
        EXPECT_EQ(r.group_images.size(), size_t(k_groups) * k_size * k_size * 3);
        for (int x = 0; x < k_size; ++x) {
            double s1 = 0, s2 = 0;
            for (int g = 0; g < k_groups; ++g) {
                double c = 0;
                for (int y = 0; y < k_size; ++y)
                    c += r.group_images[3 * ((size_t(g) * k_size + size_t(y)) * k_size + size_t(x))];
                c /= k_size;
                s1 += c;
                s2 += c * c;
            }
            const double gm = s1 / k_groups, gvar = std::max(0.0, s2 / k_groups - gm * gm) * k_groups / (k_groups - 1);
            const double m = p.mean[x];
            p.se[x] = std::sqrt(gvar / k_groups + (b_rel * m) * (b_rel * m));
        }
        p.z = student_quantile(k_z, k_groups - 1);
    }
    return p;
}

/// Columns outside the tolerance of the filtered step of `filter` (with a description).
int misses(const Profile& p, const PixelFilter& filter, std::string* out) {
    std::ostringstream os;
    int bad = 0;
    for (int x = 0; x < k_size; ++x) {
        const double expect = filter.integral_1d(k_edge - (x + 0.5));
        const double tol = p.z * p.se[x] + 1e-4;
        const bool miss = std::fabs(p.mean[x] - expect) > tol;
        bad += miss ? 1 : 0;
        if (std::fabs(x + 0.5 - k_edge) < 3.0 || miss)
            os << "column " << x << ": " << p.mean[x] << " expected " << expect << " +- " << tol
               << (miss ? "  MISS" : "") << "\n";
    }
    *out = os.str();
    return bad;
}

}  // namespace

class FilterEdge : public ::testing::TestWithParam<const char*> {};

TEST_P(FilterEdge, GaussianProfileAcrossTheEdge) {
    const std::string integrator = GetParam();
    // pssmlt/cmlt at 4096 evaluations per pixel: with the chain groups' (honest) standard
    // errors, 1024 told the gaussian from the box in 6-9 of 30 seeds, 4096 in 30 of 30
    // (and missed the gaussian's profile in 0 of 30, the worst column at 3.2 of the 4.9)
    const int spp = integrator == "pt" || integrator == "bdpt" ? 128 : 4096;
    const Profile p = render_profile(integrator, "gaussian", spp);
    std::string text;
    EXPECT_EQ(misses(p, PixelFilter::from_settings("gaussian", 0.0), &text), 0) << text;
    // resolved well enough to tell the gaussian from the box
    EXPECT_GE(misses(p, PixelFilter(), &text), 2) << text;
}

INSTANTIATE_TEST_SUITE_P(Integrators, FilterEdge, ::testing::Values("pt", "bdpt", "pssmlt", "cmlt"));

TEST(FilterEdge, MitchellOvershootsForThePathTracer) {
    const Profile p = render_profile("pt", "mitchell", 128);
    std::string text;
    const PixelFilter mitchell = PixelFilter::from_settings("mitchell", 0.0);
    EXPECT_EQ(misses(p, mitchell, &text), 0) << text;
    // the negative lobes: above 1 just inside the edge, below 0 just outside
    EXPECT_GT(mitchell.integral_1d(k_edge - 10.5), 1.0);
    EXPECT_LT(mitchell.integral_1d(k_edge - 13.5), 0.0);
}

TEST(FilterEdge, TheBoxProfileIsTheBoxs) {
    for (const char* integrator : {"pt", "cmlt"}) {
        // cmlt at 4096 evaluations per pixel: at 1024 the box and the gaussian (0.05 and 0.04
        // apart at columns 11 and 12) were told apart by one column or two, by the numbers' luck
        const Profile p = render_profile(integrator, "box", std::string(integrator) == "pt" ? 128 : 4096);
        std::string text;
        EXPECT_EQ(misses(p, PixelFilter(), &text), 0) << integrator << "\n" << text;
        EXPECT_GE(misses(p, PixelFilter::from_settings("gaussian", 0.0), &text), 2) << integrator << "\n" << text;
    }
}
