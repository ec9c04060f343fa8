#include "sampling/piecewise_constant_2d.h"

#include "util/error.h"

#include <algorithm>
#include <cmath>

namespace cmlt {

PiecewiseConstant2D::PiecewiseConstant2D(const std::vector<float>& weights, int nx, int ny)
    : m_nx(nx), m_ny(ny) {
    if (nx <= 0 || ny <= 0 || weights.size() != size_t(nx) * size_t(ny))
        CMLT_THROW(SceneError, "PiecewiseConstant2D: " << weights.size() << " weights for "
                                                       << nx << " x " << ny << " cells");
    double total = 0.0;
    for (float w : weights) {
        if (!(w >= 0.f) || !std::isfinite(w))
            CMLT_THROW(SceneError, "PiecewiseConstant2D: weights must be finite and >= 0");
        total += double(w);
    }
    const size_t n = size_t(nx) * size_t(ny);
    m_w.resize(n);
    if (!(total > 0.0)) {
        std::fill(m_w.begin(), m_w.end(), 1.f);
        total = double(n);
    } else {
        double scale = double(n) / total;
        for (size_t i = 0; i < n; ++i) m_w[i] = float(double(weights[i]) * scale);
    }
    m_marginal.assign(size_t(ny) + 1, 0.0);
    m_cond.assign(size_t(ny) * size_t(nx + 1), 0.0);
    for (int y = 0; y < ny; ++y) {
        double* c = &m_cond[size_t(y) * size_t(nx + 1)];
        double row = 0.0;
        for (int x = 0; x < nx; ++x) {
            row += double(m_w[size_t(y) * nx + x]);
            c[x + 1] = row;
        }
        if (row > 0.0) {
            for (int x = 1; x <= nx; ++x) c[x] /= row;
        } else {
            for (int x = 1; x <= nx; ++x) c[x] = double(x) / nx;  // never chosen (marginal 0)
        }
        c[nx] = 1.0;
        m_marginal[size_t(y) + 1] = m_marginal[size_t(y)] + row;
    }
    double m = m_marginal[size_t(ny)];
    for (int y = 1; y <= ny; ++y) m_marginal[size_t(y)] /= m;
    m_marginal[size_t(ny)] = 1.0;
    m_marginal_guide.resize(k_guide + 1);
    make_guide(m_marginal.data(), ny, m_marginal_guide.data());
    m_cond_guide.resize(size_t(ny) * (k_guide + 1));
    for (int y = 0; y < ny; ++y)
        make_guide(&m_cond[size_t(y) * size_t(nx + 1)], nx, &m_cond_guide[size_t(y) * (k_guide + 1)]);
}

void PiecewiseConstant2D::make_guide(const double* cdf, int n, int* guide) {
    for (int k = 0; k <= k_guide; ++k)
        guide[k] = int(std::upper_bound(cdf, cdf + n + 1, double(k) / k_guide) - cdf);
}

int PiecewiseConstant2D::invert(const double* cdf, const int* guide, int n, double u, double* frac) {
    // Last i with cdf[i] <= u, skipping empty bins. The first entry above u: between the
    // guide's bounds of u's bucket (k / k_guide <= u < (k + 1) / k_guide exactly, k_guide
    // a power of two), std::upper_bound over the whole CDF outside [0, 1) and for NaN.
    const int k = u >= 0.0 && u < 1.0 ? int(u * k_guide) : -1;
    const double* above = k >= 0 ? std::upper_bound(cdf + guide[k], cdf + guide[k + 1], u)
                                 : std::upper_bound(cdf, cdf + n + 1, u);
    int i = int(above - cdf) - 1;
    i = std::clamp(i, 0, n - 1);
    while (i > 0 && !(cdf[i + 1] > cdf[i])) --i;  // u == 1 edge: back to a non-empty bin
    while (i < n - 1 && !(cdf[i + 1] > cdf[i])) ++i;
    double width = cdf[i + 1] - cdf[i];
    double f = width > 0.0 ? (u - cdf[i]) / width : 0.5;
    *frac = std::clamp(f, 0.0, std::nextafter(1.0, 0.0));
    return i;
}

Vec2 PiecewiseConstant2D::sample(const Vec2& u, float* pdf) const {
    if (empty()) {
        *pdf = 0.f;
        return Vec2(0.f, 0.f);
    }
    double fy, fx;
    int y = invert(m_marginal.data(), m_marginal_guide.data(), m_ny, double(u.y), &fy);
    int x = invert(&m_cond[size_t(y) * size_t(m_nx + 1)], &m_cond_guide[size_t(y) * (k_guide + 1)], m_nx,
                   double(u.x), &fx);
    *pdf = m_w[size_t(y) * m_nx + x];
    float px = float((double(x) + fx) / m_nx), py = float((double(y) + fy) / m_ny);
    // Keep the point inside its cell after rounding to float.
    px = std::min(px, std::nextafter(float(x + 1) / float(m_nx), 0.f));
    py = std::min(py, std::nextafter(float(y + 1) / float(m_ny), 0.f));
    return Vec2(px, py);
}

float PiecewiseConstant2D::pdf(const Vec2& p) const {
    if (empty() || !(p.x >= 0.f && p.x <= 1.f && p.y >= 0.f && p.y <= 1.f)) return 0.f;
    int x = std::min(int(p.x * float(m_nx)), m_nx - 1);
    int y = std::min(int(p.y * float(m_ny)), m_ny - 1);
    return m_w[size_t(y) * m_nx + x];
}

}  // namespace cmlt
