// BDPT multiple importance sampling: the per-vertex area densities, the power-heuristic
// weight of a strategy by the ratio walk (pbrt-v4's MISWeight), and the debug weights of
// every strategy of one path (strategy_weights); see bdpt_tracer.h.
#include "integrators/bdpt/bdpt_detail.h"
#include "integrators/bdpt/bdpt_tracer.h"

#include "materials/bsdf.h"
#include "math/safe_math.h"
#include "scene/scene.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace cmlt {

namespace {

inline float remap0(float f) { return f != 0.f ? f : 1.f; }

}  // namespace

float BdptTracer::pdf_light(const PathVertex& v, const PathVertex& next) const {
    if (v.infinite) {
        float r = m_scene.bounds_radius();
        float pdf = 1.f / (k_pi * r * r);
        if (next.on_surface()) pdf *= std::fabs(dot(next.ng, v.w_inf));
        return pdf;
    }
    if (v.light_index < 0) return 0.f;
    Vec3 w = next.p - v.p;
    float d2 = length_squared(w);
    if (!(d2 > 0.f)) return 0.f;
    w = w / std::sqrt(d2);
    float pdf_pos, pdf_dir;
    m_scene.light(size_t(v.light_index)).pdf_le(v.p, w, &pdf_pos, &pdf_dir);
    float pdf = emission_pdf_dir(v.light_index, v.p, w, pdf_dir) / d2;
    if (next.on_surface()) pdf *= std::fabs(dot(next.ng, w));
    return pdf;
}

float BdptTracer::pdf_light_origin(const PathVertex& v, const PathVertex& next) const {
    if (v.light_index < 0) return 0.f;
    const Light& light = m_scene.light(size_t(v.light_index));
    float pmf = m_scene.light_pmf(size_t(v.light_index));
    if (v.infinite) {
        if (light.is_delta()) return pmf;  // Dirac direction; only s >= 1 can sample it
        return pmf * light.pdf_li(next.p, -v.w_inf);
    }
    Vec3 w = normalize(next.p - v.p);
    float pdf_pos, pdf_dir;
    light.pdf_le(v.p, w, &pdf_pos, &pdf_dir);
    return pmf * pdf_pos;
}

float BdptTracer::pdf(const PathVertex* prev, const PathVertex& v, const PathVertex& next) const {
    if (v.type == VertexType::light) return pdf_light(v, next);
    Vec3 wn = next.infinite ? -next.w_inf : next.p - v.p;
    float ln = length(wn);
    if (!(ln > 0.f)) return 0.f;
    wn = wn / ln;
    float pdf_sa = 0.f;
    if (v.type == VertexType::camera) {
        pdf_sa = m_importance.pdf_dir(v.p, wn);  // v.p: the lens point of this path
    } else {
        if (!prev || !v.bsdf) return 0.f;
        Vec3 wp = prev->infinite ? -prev->w_inf : prev->p - v.p;
        float lp = length(wp);
        if (!(lp > 0.f)) return 0.f;
        pdf_sa = v.bsdf->pdf(wp / lp, wn);
    }
    return convert_density(pdf_sa, v, next);
}

void BdptTracer::pdf_pair(const PathVertex& a, const PathVertex& v, const PathVertex& b, float* ab,
                          float* ba) const {
    if (v.type != VertexType::surface || !v.bsdf) {
        *ab = pdf(&a, v, b);
        *ba = pdf(&b, v, a);
        return;
    }
    // pdf for a surface vertex, both ways: a direction is the same floats whether it
    // is the one toward `next` or toward `prev`
    *ab = *ba = 0.f;
    Vec3 wa = a.infinite ? -a.w_inf : a.p - v.p;
    Vec3 wb = b.infinite ? -b.w_inf : b.p - v.p;
    const float la = length(wa), lb = length(wb);
    if (!(la > 0.f) || !(lb > 0.f)) return;
    wa = wa / la;
    wb = wb / lb;
    float to_b = 0.f, to_a = 0.f;
    v.bsdf->pdf_pair(wa, wb, &to_b, &to_a);
    *ab = convert_density(to_b, v, b);
    *ba = convert_density(to_a, v, a);
}

float BdptTracer::scatter_probability(const PathVertex& v, const PathVertex& toward) const {
    if (v.type != VertexType::surface || !v.bsdf || !m_scene.material_passes(v.si.material_id))
        return 1.f;
    Vec3 w = toward.infinite ? -toward.w_inf : toward.p - v.p;
    float l2 = length_squared(w);
    if (!(l2 > 0.f)) return 1.f;
    float p_pass = 0.f;
    v.bsdf->pass_through(w / std::sqrt(l2), &p_pass);
    return 1.f - p_pass;
}

float BdptTracer::mis_weight(const PathVertex* light, int s, const PathVertex* camera, int t,
                             const PathVertex& sampled, float conn_pass_pdf,
                             const PathVertex* pt_override) const {
    const int n = s + t;
    // A path of depth 0: (0, 2) alone, or with (1, 1) where that strategy is on.
    if (n == 2 && !direct_light_tracing(s == 0 ? (pt_override ? *pt_override : camera[1]) : light[0]))
        return 1.f;
    // Path vertices x_0 (light end) .. x_{n-1} (camera), with their light-side (pl) and
    // camera-side (pe) area densities; the four vertices next to the connection get the
    // densities this connection implies.
    constexpr int k_max = 1024 + 4;
    const PathVertex* x[k_max];
    float pl[k_max], pe[k_max];
    bool delta[k_max];
    if (n > k_max) return 0.f;
    for (int i = 0; i < n; ++i) {
        if (i < s) {
            // s = 1 samples its light vertex (`sampled`) except for (1, 1), whose light
            // vertex is the light subpath's origin and whose `sampled` is the lens point
            x[i] = (s == 1 && i == 0 && t != 1) ? &sampled : &light[i];
            pl[i] = x[i]->pdf_fwd;
            pe[i] = x[i]->pdf_rev;
        } else {
            int j = n - 1 - i;
            x[i] = (t == 1 && j == 0) ? &sampled : &camera[j];
            if (pt_override && j == t - 1) x[i] = pt_override;
            pe[i] = x[i]->pdf_fwd;
            pl[i] = x[i]->pdf_rev;
        }
        delta[i] = x[i]->delta;
    }
    const PathVertex* qs = s > 0 ? x[s - 1] : nullptr;
    const PathVertex* qs_minus = s > 1 ? x[s - 2] : nullptr;
    const PathVertex* pt = x[s];
    const PathVertex* pt_minus = t > 1 ? x[s + 1] : nullptr;
    // pt: light-side density. A density across a segment includes the probabilities of
    // the pass-through crossings on it: conn_pass_pdf for the connection segment,
    // pt->pass_pdf for pt - pt_minus and qs->pass_pdf for qs_minus - qs (1 without
    // pass-through surfaces).
    // (the two densities at qs, and the two at pt, in pairs: pdf_pair)
    if (qs_minus) {
        float to_pt, to_qs_minus;
        pdf_pair(*qs_minus, *qs, *pt, &to_pt, &to_qs_minus);
        pl[s] = to_pt * conn_pass_pdf;
        pe[s - 2] = to_qs_minus * qs->pass_pdf;
    } else {
        pl[s] = s > 0 ? pdf(qs_minus, *qs, *pt) * conn_pass_pdf : pdf_light_origin(*pt, *pt_minus);
    }
    if (qs && pt_minus) {
        float to_pt_minus, to_qs;
        pdf_pair(*qs, *pt, *pt_minus, &to_pt_minus, &to_qs);
        pl[s + 1] = to_pt_minus * pt->pass_pdf;
        pe[s - 1] = to_qs * conn_pass_pdf;
    } else {
        if (pt_minus) pl[s + 1] = (s > 0 ? pdf(qs, *pt, *pt_minus) : pdf_light(*pt, *pt_minus)) * pt->pass_pdf;
        if (qs) pe[s - 1] = pdf(pt_minus, *pt, *qs) * conn_pass_pdf;
    }
    delta[s] = false;
    if (s > 0) delta[s - 1] = false;

    // Subpath ends on a surface that may pass rays exist only with the probability that
    // the walk reaching them scattered there rather than crossed (interior vertices
    // too, but there it cancels against the next direction's conditional density):
    // strategy s' has the extra factor ends(s') = e_l(x_{s'-1}) e_c(x_{s'}), e_l / e_c
    // the scattering probability of a walk arriving from the light / camera side.
    float el[k_max], ec[k_max];
    const bool passing = m_scene.has_pass_through();
    if (passing) {
        for (int i = 0; i < n; ++i) {
            el[i] = i > 0 ? scatter_probability(*x[i], *x[i - 1]) : 1.f;
            ec[i] = i + 1 < n ? scatter_probability(*x[i], *x[i + 1]) : 1.f;
        }
    }
    auto ends = [&](int sp) { return double(sp > 0 ? el[sp - 1] : 1.f) * double(ec[sp]); };
    const double ends_here = passing ? ends(s) : 1.0;
    if (!(ends_here > 0.0)) return 0.f;

    double sum = 0.0, ri = 1.0;
    // Move the connection toward the camera: strategies s' = s+1 .. n-1.
    for (int i = s; i <= n - 2; ++i) {
        ri *= double(remap0(pl[i])) / double(remap0(pe[i]));
        if (delta[i] || delta[i + 1]) continue;
        const double r = passing ? ri * ends(i + 1) / ends_here : ri;
        sum += r * r;
    }
    // Toward the light: s' = s-1 .. 0.
    ri = 1.0;
    for (int i = s - 1; i >= 0; --i) {
        ri *= double(remap0(pe[i])) / double(remap0(pl[i]));
        bool delta_prev = i > 0 ? delta[i - 1] : is_delta_light(*x[0]);
        if (delta[i] || delta_prev) continue;
        const double r = passing ? ri * ends(i) / ends_here : ri;
        sum += r * r;
    }
    double w = 1.0 / (1.0 + sum);
    return std::isfinite(w) ? float(w) : 0.f;
}

std::vector<float> BdptTracer::strategy_weights(const PathVertex* light, int s,
                                                const PathVertex* camera, int t,
                                                const PathVertex& sampled,
                                                float* weight_here) const {
    const int n = s + t;
    // The whole path, light end first.
    std::vector<PathVertex> x(static_cast<size_t>(n));
    for (int i = 0; i < s; ++i) x[size_t(i)] = (s == 1 && t != 1) ? sampled : light[i];
    for (int j = 0; j < t; ++j) x[size_t(n - 1 - j)] = (t == 1 && j == 0) ? sampled : camera[j];
    // Pass-through crossings of each segment x_i - x_{i+1}: their probability product, as
    // a connection over that segment would find it (x_{i+1} is never an infinite light).
    std::vector<float> seg(static_cast<size_t>(std::max(n - 1, 0)), 1.f);
    for (int i = 0; i + 1 < n; ++i)
        m_scene.transmittance(connection_ray(x[size_t(i + 1)], x[size_t(i)]), &seg[size_t(i)]);
    if (weight_here)
        *weight_here = mis_weight(light, s, camera, t, sampled, s > 0 ? seg[size_t(s - 1)] : 1.f);
    // x_0 as a light vertex (a camera subpath may have reached it as an emissive surface).
    if (x[0].type == VertexType::surface && x[0].light_index >= 0) {
        PathVertex lv;
        lv.type = VertexType::light;
        lv.light_index = x[0].light_index;
        lv.p = x[0].p;
        lv.ng = lv.ns = m_scene.light(size_t(lv.light_index)).emitter_normal(lv.p);
        lv.error_scale = x[0].error_scale;
        x[0] = lv;
    }
    // The connection vertices scatter through the connection (a non-Dirac evaluation): their
    // `delta` flags tell how their own subpath continued beyond this path, which is not part
    // of it (a smooth-clearcoat vertex whose subpath went on through the Dirac coat lobe is
    // a rough scattering here). Every other vertex's flag describes its scattering in the
    // path.
    if (s > 0) x[size_t(s - 1)].delta = false;
    x[size_t(s)].delta = false;
    // Density of `v` generated through `mid`: 0 where the path scatters at `mid` through a
    // Dirac lobe, as the random walk stores it (a mixed Dirac / rough vertex would
    // otherwise give its rough lobe's density at the mirror direction).
    auto pdf_through = [&](const PathVertex* prev, const PathVertex& mid, const PathVertex& v) {
        return mid.delta ? 0.f : pdf(prev, mid, v);
    };
    std::vector<float> weights(static_cast<size_t>(n), 0.f);
    std::vector<PathVertex> L(static_cast<size_t>(n)), C(static_cast<size_t>(n));
    for (int sp = 0; sp < n; ++sp) {
        const int tp = n - sp;
        // Can strategy (sp, tp) make this path?
        bool ok = !(sp == 1 && tp == 1) || direct_light_tracing(x[0]);
        if (sp == 0) {
            ok = ok && x[0].type == VertexType::light && !is_delta_light(x[0]);
        } else {
            ok = ok && !x[size_t(sp - 1)].delta && !x[size_t(sp)].delta &&
                 connectible(x[size_t(sp - 1)]) && connectible(x[size_t(sp)]);
        }
        if (!ok) continue;
        // Light subpath x_0 .. x_{sp-1} with the densities its random walk would store.
        for (int i = 0; i < sp; ++i) {
            PathVertex v = x[size_t(i)];
            if (i == 0) v.pdf_fwd = pdf_light_origin(v, x[1]);
            else if (i == 1) v.pdf_fwd = pdf_light(x[0], v) * seg[0];
            else v.pdf_fwd = pdf_through(&x[size_t(i - 2)], x[size_t(i - 1)], v) * seg[size_t(i - 1)];
            v.pdf_rev = (i + 2 < n) ? pdf_through(&x[size_t(i + 2)], x[size_t(i + 1)], v)
                        : (i + 1 < n ? pdf(nullptr, x[size_t(i + 1)], v) : 0.f);
            if (i + 1 < n) v.pdf_rev *= seg[size_t(i)];
            v.pass_pdf = i > 0 ? seg[size_t(i - 1)] : 1.f;
            L[size_t(i)] = v;
        }
        // Camera subpath x_{n-1} .. x_{sp}.
        for (int j = 0; j < tp; ++j) {
            int i = n - 1 - j;
            PathVertex v = x[size_t(i)];
            if (j == 0) v.pdf_fwd = 1.f;
            else if (j == 1) v.pdf_fwd = pdf(nullptr, x[size_t(n - 1)], v) * seg[size_t(i)];
            else v.pdf_fwd = pdf_through(&x[size_t(i + 2)], x[size_t(i + 1)], v) * seg[size_t(i)];
            if (i == 0) v.pdf_rev = 0.f;
            else if (i == 1) v.pdf_rev = pdf_light(x[0], v) * seg[0];
            else v.pdf_rev = pdf_through(&x[size_t(i - 2)], x[size_t(i - 1)], v) * seg[size_t(i - 1)];
            v.pass_pdf = j > 0 ? seg[size_t(i)] : 1.f;
            C[size_t(j)] = v;
        }
        const PathVertex& samp = tp == 1 ? C[0] : (sp == 1 ? L[0] : sampled);
        weights[size_t(sp)] =
            mis_weight(L.data(), sp, C.data(), tp, samp, sp > 0 ? seg[size_t(sp - 1)] : 1.f);
    }
    return weights;
}

}  // namespace cmlt
