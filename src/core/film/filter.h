#pragma once
/// \file Pixel reconstruction filters: box, triangle, gaussian, mitchell, blackman-harris.
///
/// Every filter is separable, f(x, y) = f1(x) f1(y), with support [-r, r]^2 (r: the
/// radius in pixels) and is normalised so that it integrates to 1 over the plane; a
/// pixel's value is then the filtered image at its centre, I_j = ∫ f(p - c_j) I(p) dp.
///
/// 1-D profiles g(x) on |x| <= r (normalised numerically to ∫ f1 = 1):
///  * box: 1 (radius 0.5 is the one-pixel box of the unfiltered film);
///  * triangle: r - |x|;
///  * gaussian: exp(-x²/2σ²) - exp(-r²/2σ²) with σ = r/3 (pbrt-v4's default: r 1.5,
///    σ 0.5; the value at the radius is subtracted so it reaches 0 there);
///  * mitchell: Mitchell-Netravali with B = C = 1/3 over 2|x|/r (negative lobes);
///  * blackman-harris: the four-term Blackman-Harris window spanning [-r, r].
/// Default radii: box 0.5, triangle 1, gaussian 1.5, mitchell 2, blackman-harris 1.5.
///
/// Sampling (filter importance sampling): sample() draws an offset with a density
/// proportional to |f| — exact for the box, otherwise per axis from a tabulated inverse
/// CDF of |f1| (piecewise-constant, k_table_bins bins: each bin's mean |f1|), the 2-D
/// sample being the product of the two axes' — and returns the weight f/pdf, negative
/// where the filter is. E[weight · h(offset)] = ∫ f h for any h, so a pixel sample at
/// c_j + offset weighted by `weight` estimates I_j without bias and stays in its pixel.
///
/// Splatting (a contribution at a continuous film position p reaches every pixel whose
/// centre lies within the radius): footprint() gives the pixels and the weights
/// f(c_j - p). The weights of one splat sum to about 1 (exactly 1 on average over p: ∫ f
/// = 1), so the image estimates the same filtered I_j as the sampled pixels do.
///
/// The splat weights (footprint(), splat(), and the pass splatter's) are f1 read from a
/// table: f1 at k_weight_bins + 1 evenly spaced |x| in [0, r], linearly interpolated
/// (weight_1d; every profile is even). A splat costs a few multiply-adds per pixel
/// instead of a transcendental (the gaussian's exp, blackman-harris' cosines). The table
/// is exact at its nodes, and between them off by at most h²/8 · max |f1''| (h = r /
/// k_weight_bins): ~1e-6 of the peak for the default gaussian, below a float's
/// resolution of a pixel value after the film's sums; the box and the triangle are
/// linear between nodes (the triangle's kink at 0 is a node) and so exact up to rounding.
/// The weights still sum to 1 on average over p to that accuracy, so nothing is biased
/// beyond it (the pass splatter's ratio A / B does not depend on the weights' scale at
/// all). evaluate_1d stays the exact profile (sampling, normalisation, tests).
#include "math/vec.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace cmlt {

enum class FilterKind { box, triangle, gaussian, mitchell, blackman_harris };

class PixelFilter {
public:
    static constexpr int k_table_bins = 512;  ///< bins of each axis' inverse-CDF table
    static constexpr int k_max_footprint = 8;  ///< pixels per axis a splat can reach
    static constexpr int k_weight_bins = 1024;  ///< intervals of the splat-weight table on [0, r]

    /// The unit box (radius 0.5): the one-pixel film.
    PixelFilter() : PixelFilter(FilterKind::box, 0.5) {}
    /// `radius` in pixels, (0, (k_max_footprint - 1) / 2]; throws SettingsError otherwise.
    PixelFilter(FilterKind kind, double radius);
    /// From the settings' names: "box", "triangle", "gaussian", "mitchell",
    /// "blackman-harris"; radius 0 = the filter's default radius. Throws SettingsError
    /// naming the setting for an unknown name or a bad radius.
    static PixelFilter from_settings(const std::string& name, double radius);
    static double default_radius(FilterKind kind);
    static const char* name_of(FilterKind kind);

    FilterKind kind() const { return m_kind; }
    const char* name() const { return name_of(m_kind); }
    double radius() const { return m_radius; }
    /// The one-pixel box: samples land in their pixel exactly as without a filter.
    bool unit_box() const { return m_unit_box; }
    /// How far film positions reach beyond the image so that every pixel's footprint is
    /// covered (a splatting film samples [-m, W + m) x [-m, H + m)): r - 1/2; 0 for the
    /// unit box.
    float margin() const { return m_unit_box ? 0.f : float(m_radius - 0.5); }
    /// Area of that window for a W x H image, in pixels (W·H for the unit box).
    double window_area(int width, int height) const {
        return (double(width) + 2.0 * double(margin())) * (double(height) + 2.0 * double(margin()));
    }

    /// Normalised 1-D profile f1(x) (∫ f1 = 1), 0 for |x| > r.
    double evaluate_1d(double x) const;
    /// f(x, y) = f1(x) f1(y) (∫∫ f = 1).
    double evaluate(double x, double y) const { return evaluate_1d(x) * evaluate_1d(y); }
    /// f1(x) as the splatting films weigh with it: the table of the file comment, 0 for
    /// |x| > r.
    double weight_1d(double x) const {
        const double t = std::fabs(x) * m_weight_scale;
        if (!(t <= double(k_weight_bins))) return 0.0;  // beyond the radius (or NaN)
        const int i = std::min(int(t), k_weight_bins - 1);
        const double a = m_weights[size_t(i)], b = m_weights[size_t(i) + 1];
        return a + (b - a) * (t - double(i));
    }
    /// ∫_{-r}^{x} f1: the filtered unit step's profile (numerical, 1e-9 accurate).
    double integral_1d(double x) const;

    /// 1 / ∫∫ f²: a splatting film's (film/pass_splatter.h) pixels average about this
    /// many samples each, so a sum over many neighbouring pixels has about this times
    /// the sum of their variances (1 for the unit box; 9 for a box of radius 1.5; ~3.1
    /// for the default gaussian).
    double splat_correlation() const { return m_splat_correlation; }

    struct Sample {
        Vec2 offset;        ///< from the pixel centre, in pixels, within [-r, r]^2
        float weight = 1.f; ///< f(offset) / pdf(offset), with f's sign
    };
    /// An offset for u ∈ [0, 1)^2 (see the file comment).
    Sample sample(const Vec2& u) const;
    /// Density of sample()'s offsets (per pixel², 0 outside the support).
    double pdf(double x, double y) const { return pdf_1d(x) * pdf_1d(y); }
    double pdf_1d(double x) const;

    /// The film position of a pixel sample of pixel (x, y) for u ∈ [0, 1)^2 and its
    /// weight: pixel (x, y) + u for the unit box (bit for bit the unfiltered position,
    /// weight 1), else the pixel's centre + sample(u).offset.
    Vec2 film_position(int x, int y, const Vec2& u, float* weight) const {
        if (!m_unit_box) return sampled_position(x, y, u, weight);
        *weight = 1.f;
        return Vec2(float(x) + u.x, float(y) + u.y);
    }

    /// The pixels of a W x H image whose centres lie within the radius of film position
    /// p, with their weights f(c - p): calls emit(pixel = y·W + x, weight) for each
    /// pixel of nonzero weight, rows then columns in increasing order. The unit box:
    /// the pixel containing p (clamped into the image), weight 1.
    template <class Emit>
    void footprint(const Vec2& p, int width, int height, Emit&& emit) const {
        if (m_unit_box) {
            const int x = std::min(width - 1, std::max(0, int(std::floor(p.x))));
            const int y = std::min(height - 1, std::max(0, int(std::floor(p.y))));
            emit(uint32_t(y) * uint32_t(width) + uint32_t(x), 1.0);
            return;
        }
        int x0, y0, nx, ny;
        double wx[k_max_footprint], wy[k_max_footprint];
        axis_weights(p.x, width, &x0, &nx, wx);
        axis_weights(p.y, height, &y0, &ny, wy);
        for (int j = 0; j < ny; ++j) {
            if (wy[j] == 0.0) continue;
            for (int i = 0; i < nx; ++i)
                if (wx[i] != 0.0)
                    emit(uint32_t(y0 + j) * uint32_t(width) + uint32_t(x0 + i), wx[i] * wy[j]);
        }
    }

    /// Add a light-tracing splat of value `L` at film position `p` to the W x H x 3
    /// double image `img` over footprint(), each weight times `scale` (the bdpt
    /// integrator's and the Metropolis direct pass's (1, 1) splats).
    void splat(const Vec2& p, const Vec3& L, double scale, int width, int height, double* img) const {
        footprint(p, width, height, [&](uint32_t pixel, double w) {
            double* d = &img[3 * size_t(pixel)];
            w *= scale;
            d[0] += double(L.x) * w;
            d[1] += double(L.y) * w;
            d[2] += double(L.z) * w;
        });
    }

private:
    double profile(double x) const;  ///< unnormalised g(x), |x| <= r
    Vec2 sampled_position(int x, int y, const Vec2& u, float* weight) const;  ///< film_position's filters but the box
    /// Pixels [*first, *first + *n) of an axis of `size` pixels around coordinate p, with
    /// weights weight_1d(centre - p) (the separable part of footprint()).
    void axis_weights(float p, int size, int* first, int* n, double* w) const;

    FilterKind m_kind;
    double m_radius;
    bool m_unit_box;
    double m_norm = 1.0;        ///< 1 / ∫ g
    double m_gauss_floor = 0.0; ///< gaussian: exp(-r²/2σ²)
    double m_splat_correlation = 1.0;
    std::vector<double> m_cdf;  ///< k_table_bins + 1 entries of the |f1| table
    std::vector<double> m_pdf;  ///< per bin, density per pixel
    std::vector<double> m_weights;  ///< f1 at |x| = i r / k_weight_bins, i = 0 .. k_weight_bins
    double m_weight_scale = 0.0;    ///< k_weight_bins / r
};

}  // namespace cmlt
