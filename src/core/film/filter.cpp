// Pixel reconstruction filters; see filter.h.
#include "film/filter.h"

#include "util/error.h"

#include <algorithm>
#include <cmath>

namespace cmlt {

namespace {

constexpr double k_pi = 3.14159265358979323846;
constexpr double k_mitchell_b = 1.0 / 3.0, k_mitchell_c = 1.0 / 3.0;

/// Mitchell-Netravali over x in [0, 2].
double mitchell(double x) {
    const double B = k_mitchell_b, C = k_mitchell_c;
    x = std::fabs(x);
    if (x <= 1.0)
        return ((12 - 9 * B - 6 * C) * x * x * x + (-18 + 12 * B + 6 * C) * x * x + (6 - 2 * B)) / 6.0;
    if (x <= 2.0)
        return ((-B - 6 * C) * x * x * x + (6 * B + 30 * C) * x * x + (-12 * B - 48 * C) * x + (8 * B + 24 * C)) /
               6.0;
    return 0.0;
}

/// Composite Simpson of h over [a, b] with n (even) intervals.
template <class H>
double simpson(const H& h, double a, double b, int n) {
    if (!(b > a)) return 0.0;
    const double dx = (b - a) / n;
    double s = h(a) + h(b);
    for (int i = 1; i < n; ++i) s += h(a + i * dx) * (i % 2 ? 4.0 : 2.0);
    return s * dx / 3.0;
}

/// ∫_a^b h, split where the profiles have kinks (0, ±r/2) so each piece is smooth.
template <class H>
double integrate_profile(const H& h, double r, double a, double b, int n_per_piece) {
    const double knots[5] = {-r, -0.5 * r, 0.0, 0.5 * r, r};
    double s = 0.0;
    for (int k = 0; k < 4; ++k) {
        const double lo = std::max(a, knots[k]), hi = std::min(b, knots[k + 1]);
        if (hi > lo) s += simpson(h, lo, hi, n_per_piece);
    }
    return s;
}

}  // namespace

double PixelFilter::default_radius(FilterKind kind) {
    switch (kind) {
    case FilterKind::box: return 0.5;
    case FilterKind::triangle: return 1.0;
    case FilterKind::gaussian: return 1.5;
    case FilterKind::mitchell: return 2.0;
    case FilterKind::blackman_harris: return 1.5;
    }
    return 0.5;
}

const char* PixelFilter::name_of(FilterKind kind) {
    switch (kind) {
    case FilterKind::box: return "box";
    case FilterKind::triangle: return "triangle";
    case FilterKind::gaussian: return "gaussian";
    case FilterKind::mitchell: return "mitchell";
    case FilterKind::blackman_harris: return "blackman-harris";
    }
    return "box";
}

PixelFilter PixelFilter::from_settings(const std::string& name, double radius) {
    for (FilterKind k : {FilterKind::box, FilterKind::triangle, FilterKind::gaussian, FilterKind::mitchell,
                         FilterKind::blackman_harris})
        if (name == name_of(k)) return PixelFilter(k, radius == 0.0 ? default_radius(k) : radius);
    CMLT_THROW(SettingsError, "RenderSettings.pixel_filter: unknown filter '"
                                  << name << "' (available: box, triangle, gaussian, mitchell, blackman-harris)");
}

PixelFilter::PixelFilter(FilterKind kind, double radius) : m_kind(kind), m_radius(radius) {
    const double max_radius = 0.5 * (k_max_footprint - 1);
    if (!(radius > 0.0 && radius <= max_radius))
        CMLT_THROW(SettingsError, "RenderSettings.filter_radius: must be in (0, " << max_radius << "] pixels, got "
                                                                                   << radius);
    m_unit_box = kind == FilterKind::box && radius == 0.5;
    if (kind == FilterKind::gaussian) {
        const double sigma = radius / 3.0;
        m_gauss_floor = std::exp(-radius * radius / (2 * sigma * sigma));
    }
    const double r = m_radius;
    m_norm = 1.0 / integrate_profile([&](double x) { return profile(x); }, r, -r, r, 1024);
    if (!m_unit_box) {
        const double f2 = integrate_profile([&](double x) { return evaluate_1d(x) * evaluate_1d(x); }, r, -r, r, 1024);
        m_splat_correlation = 1.0 / (f2 * f2);
    }

    // splat weights: f1 at the table's nodes (the last one exactly the radius)
    m_weights.resize(size_t(k_weight_bins) + 1);
    for (int i = 0; i <= k_weight_bins; ++i)
        m_weights[size_t(i)] = evaluate_1d(i == k_weight_bins ? r : r * double(i) / double(k_weight_bins));
    m_weight_scale = double(k_weight_bins) / r;

    // inverse-CDF table of |f1|: each bin's mean |f1|
    const int n = k_table_bins;
    const double dx = 2 * r / n;
    m_pdf.assign(size_t(n), 0.0);
    m_cdf.assign(size_t(n) + 1, 0.0);
    const auto abs_f1 = [&](double x) { return std::fabs(evaluate_1d(x)); };
    double total = 0.0;
    for (int b = 0; b < n; ++b) {
        m_pdf[size_t(b)] = simpson(abs_f1, -r + b * dx, -r + (b + 1) * dx, 16) / dx;
        total += m_pdf[size_t(b)] * dx;
    }
    for (int b = 0; b < n; ++b) {
        m_pdf[size_t(b)] /= total;
        m_cdf[size_t(b) + 1] = m_cdf[size_t(b)] + m_pdf[size_t(b)] * dx;
    }
    for (int b = 1; b <= n; ++b) m_cdf[size_t(b)] /= m_cdf[size_t(n)];
}

double PixelFilter::profile(double x) const {
    const double r = m_radius;
    if (std::fabs(x) > r) return 0.0;
    switch (m_kind) {
    case FilterKind::box: return 1.0;
    case FilterKind::triangle: return r - std::fabs(x);
    case FilterKind::gaussian: {
        const double sigma = r / 3.0;
        return std::max(0.0, std::exp(-x * x / (2 * sigma * sigma)) - m_gauss_floor);
    }
    case FilterKind::mitchell: return mitchell(2.0 * x / r);
    case FilterKind::blackman_harris: {
        const double t = (x + r) / (2 * r);
        return 0.35875 - 0.48829 * std::cos(2 * k_pi * t) + 0.14128 * std::cos(4 * k_pi * t) -
               0.01168 * std::cos(6 * k_pi * t);
    }
    }
    return 0.0;
}

double PixelFilter::evaluate_1d(double x) const { return profile(x) * m_norm; }

double PixelFilter::integral_1d(double x) const {
    const double r = m_radius;
    if (x <= -r) return 0.0;
    return integrate_profile([&](double t) { return evaluate_1d(t); }, r, -r, std::min(x, r), 512);
}

double PixelFilter::pdf_1d(double x) const {
    if (m_unit_box) return std::fabs(x) <= 0.5 ? 1.0 : 0.0;
    const double r = m_radius;
    if (!(std::fabs(x) <= r)) return 0.0;
    const int n = k_table_bins;
    const int b = std::min(n - 1, int((x + r) / (2 * r) * n));
    return m_pdf[size_t(b)];
}

PixelFilter::Sample PixelFilter::sample(const Vec2& u) const {
    Sample s;
    if (m_unit_box) {
        s.offset = Vec2(u.x - 0.5f, u.y - 0.5f);
        return s;
    }
    const double r = m_radius, dx = 2 * r / k_table_bins;
    double w = 1.0;
    float o[2];
    for (int a = 0; a < 2; ++a) {
        const double ua = a == 0 ? u.x : u.y;
        // the bin b with cdf[b] <= u < cdf[b + 1] (bins of zero mass are never chosen)
        const auto it = std::upper_bound(m_cdf.begin() + 1, m_cdf.end() - 1, ua);
        const int b = int(it - m_cdf.begin()) - 1;
        const double c0 = m_cdf[size_t(b)], c1 = m_cdf[size_t(b) + 1];
        const double frac = c1 > c0 ? std::min(1.0, std::max(0.0, (ua - c0) / (c1 - c0))) : 0.5;
        const double x = std::min(r, std::max(-r, -r + (b + frac) * dx));
        o[a] = float(x);
        w *= evaluate_1d(double(o[a])) / m_pdf[size_t(b)];
    }
    s.offset = Vec2(o[0], o[1]);
    s.weight = float(w);
    return s;
}

Vec2 PixelFilter::sampled_position(int x, int y, const Vec2& u, float* weight) const {
    const Sample s = sample(u);
    *weight = s.weight;
    return Vec2(float(x) + 0.5f + s.offset.x, float(y) + 0.5f + s.offset.y);
}

void PixelFilter::axis_weights(float p, int size, int* first, int* n, double* w) const {
    // centres i + 0.5 with |i + 0.5 - p| <= r
    const double r = m_radius;
    const int lo = std::max(0, int(std::ceil(double(p) - r - 0.5)));
    const int hi = std::min(size - 1, int(std::floor(double(p) + r - 0.5)));
    *first = lo;
    *n = 0;
    for (int i = lo; i <= hi && *n < k_max_footprint; ++i) w[(*n)++] = weight_1d(double(i) + 0.5 - double(p));
}

}  // namespace cmlt
