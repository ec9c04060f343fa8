// BDPT connections: joining a light and a camera subpath (s = 0 emitter hits, s = 1
// light sampling, t = 1 light tracing onto the lens, general s, t), split at the
// visibility query for the resumable strategy; see bdpt_tracer.h.
#include "integrators/bdpt/bdpt_detail.h"
#include "integrators/bdpt/bdpt_tracer.h"

#include "materials/bsdf.h"
#include "math/safe_math.h"
#include "scene/scene.h"

#include <cmath>

namespace cmlt {

using bdpt_detail::leave_point;
using bdpt_detail::mode_of;

Spectrum BdptTracer::scatter(const PathVertex& v, const Vec3& w, bool importance) const {
    if (v.type != VertexType::surface || !v.bsdf) return Spectrum(0.f);
    const Bsdf& b = *v.bsdf;
    Spectrum f = b.eval(v.wo, w, mode_of(importance));
    if (is_black(f)) return f;
    if (!importance) return f * std::fabs(dot(v.ns, w));
    // Adjoint BSDF with the shading-normal correction, times the geometric cosine.
    float den = std::fabs(dot(v.wo, v.si.ng));
    if (!(den > 0.f)) return Spectrum(0.f);
    return f * (std::fabs(dot(v.wo, v.ns)) * std::fabs(dot(w, v.si.ng)) / den);
}

Ray BdptTracer::connection_ray(const PathVertex& a, const PathVertex& b) const {
    Ray r;
    if (b.infinite) {
        Vec3 w = -b.w_inf;
        r = Ray(leave_point(a, w), w, 0.f, k_infinity);
    } else {
        Vec3 pa = leave_point(a, b.p - a.p);
        Vec3 pb = leave_point(b, a.p - b.p);
        r = Ray(pa, pb - pa, 0.f, 1.f - k_shadow_epsilon);
    }
    r.time = a.time;  // both subpaths share the sample's time
    return r;
}

bool BdptTracer::caustic_path(const PathVertex* light, int s, const PathVertex* camera, int t) const {
    // The scattering vertices from the camera's side: camera[1 .. t-1] (camera[t-1] is
    // the light end for s = 0), then light[s-1 .. 1] (light[0] is the light end).
    auto specular = [&](const PathVertex& v) {
        return v.type == VertexType::surface && m_partition->specular(v.si.material_id);
    };
    const int tc = s == 0 ? t - 1 : t;  // camera vertices before the light end
    bool diffuse_before = false, last_specular = false, any = false, first_specular = false;
    int n_diffuse = 0;
    auto visit = [&](const PathVertex& v) {
        if (any) diffuse_before = diffuse_before || !last_specular;
        last_specular = specular(v);
        if (!any) first_specular = last_specular;
        if (!last_specular && n_diffuse < 2) ++n_diffuse;
        any = true;
    };
    for (int i = 1; i < tc; ++i) visit(camera[i]);
    for (int j = s - 1; j >= 1; --j) visit(light[j]);
    if (!any || !m_partition->has_traced())
        return m_partition->caustic(last_specular, diffuse_before, first_specular, n_diffuse);
    // The light-traced caustics: whether z1 and z_{n−1} scattered by a Dirac lobe (a
    // vertex's `delta`, except at the connection's two ends, which scatter through the
    // BSDF's value: never Dirac) and the light at the end.
    auto dirac = [&](bool on_camera, int index) {
        const bool end = s > 0 && (on_camera ? index == t - 1 : index == s - 1);
        return !end && (on_camera ? camera[index] : light[index]).delta;
    };
    const bool first_dirac = tc > 1 ? dirac(true, 1) : dirac(false, s - 1);
    const bool last_dirac = s >= 2 ? dirac(false, 1) : dirac(true, tc - 1);
    const int32_t light_index = s == 0 ? camera[t - 1].light_index : s >= 2 ? light[0].light_index : -1;
    return m_partition->caustic(last_specular, diffuse_before, first_specular, n_diffuse,
                                m_partition->traced(first_dirac, last_dirac, light_index));
}

bool BdptTracer::begin_connect(const PathVertex* light, int s, const PathVertex* camera, int t,
                               BdptSampler& sampler, bool mis, BdptCounters& c,
                               BdptConnection& k) const {
    const Scene& scene = m_scene;
    k.light = light;
    k.camera = camera;
    k.s = s;
    k.t = t;
    k.mis = mis;
    k.tail = false;
    k.L = Spectrum(0.f);
    k.result = Spectrum(0.f);
    Spectrum& L = k.L;
    PathVertex& sampled = k.sampled;
    if (t > 1 && s != 0 && camera[t - 1].type == VertexType::light) return false;
    if (m_partition && !m_partition->wants(caustic_path(light, s, camera, t))) return false;

    // A shadow ray a - b to be answered before finish_connect (as a visibility query).
    auto visibility = [&](const PathVertex& a, const PathVertex& b) {
        c.shadow_rays += 1;
        c.rays += 1;
        k.shadow = connection_ray(a, b);
        return true;
    };
    if (s == 0) {
        const PathVertex& pt = camera[t - 1];
        if (pt.infinite) {
            // Each infinite light is its own emitter with its own weight.
            Spectrum sum(0.f);
            PathVertex tmp = pt;
            for (uint32_t li : scene.infinite_lights()) {
                const Light& l = scene.light(li);
                Spectrum le = l.le_escape(-pt.w_inf);
                if (is_black(le)) continue;
                tmp.light_index = int32_t(li);
                Spectrum Ll = pt.beta * le;
                float w = mis ? mis_weight(light, 0, camera, t, sampled, 1.f, &tmp) : 1.f;
                sum += Ll * w;
            }
            k.result = sum;
            return false;
        }
        if (pt.light_index < 0 || is_black(pt.le)) return false;
        L = pt.beta * pt.le;
        k.result = connect_tail(k, 1.f);
        return false;
    }
    if (t == 1) {
        const PathVertex& qs = light[s - 1];
        if (!connectible(qs) || !m_importance.connectable()) return false;
        // The camera end: a lens point (connection stream, drawn only with a thin lens:
        // pbrt-v4's SampleWi) or the pinhole.
        const Vec3 p_lens = m_importance.sample_lens(m_importance.has_lens() ? sampler.next2d()
                                                                             : Vec2(0.f, 0.f));
        Vec3 w = p_lens - qs.p;
        float d2 = length_squared(w);
        if (!(d2 > 0.f)) return false;
        w = w / std::sqrt(d2);
        Vec2 pr;
        float we = m_importance.we(p_lens, -w, &pr);
        if (!(we > 0.f)) return false;
        sampled.reset(VertexType::camera);
        sampled.time = qs.time;
        sampled.p = p_lens;
        sampled.beta = Spectrum(1.f);
        // We G / p_lens, G = cos_cam / d2 (the lens point has no cosine at qs's end
        // beyond scatter's): the lens density cancels We's 1 / A_lens.
        const float cos_cam = m_importance.cos_axis(-w);
        if (qs.type == VertexType::light) {
            // (1, 1): the light's origin vertex itself, Le toward the lens times its
            // cosine over the density of the point (pdf_fwd: light pmf x area density)
            if (!direct_light_tracing(qs)) return false;
            Spectrum le;
            m_scene.light(size_t(qs.light_index)).le_toward(qs.p, w, &le);
            const float cos_l = std::fabs(dot(qs.ng, w));
            if (!(qs.pdf_fwd > 0.f)) return false;
            L = le * (cos_l / qs.pdf_fwd) * (we * cos_cam / (d2 * m_importance.pdf_lens()));
        } else {
            L = qs.beta * scatter(qs, w, true) * (we * cos_cam / (d2 * m_importance.pdf_lens()));
        }
        if (is_black(L)) return false;
        k.p_raster = pr;
        return visibility(qs, sampled);
    }
    if (s == 1) {
        const PathVertex& pt = camera[t - 1];
        if (!connectible(pt) || scene.light_count() == 0) return false;
        float u_light = sampler.next1d();
        Vec2 u_pos = sampler.next2d();
        float pmf = 0.f;
        size_t li = scene.sample_light(u_light, &pmf);
        const Light& l = scene.light(li);
        LightSample ls = l.sample_li(pt.p, u_pos);
        if (!ls.valid() || !(pmf > 0.f)) return false;
        sampled.reset(VertexType::light);
        sampled.time = pt.time;
        sampled.light_index = int32_t(li);
        if (std::isinf(ls.dist)) {
            sampled.infinite = true;
            sampled.w_inf = -ls.wi;
        } else {
            sampled.p = ls.p_light;
            sampled.ng = sampled.ns =
                is_black(ls.n_light) ? l.emitter_normal(ls.p_light) : ls.n_light;
            sampled.error_scale =
                ls.error_scale > 0.f ? ls.error_scale : point_error_scale(ls.p_light);
        }
        sampled.beta = ls.li / (pmf * ls.pdf);
        sampled.pdf_fwd = pdf_light_origin(sampled, pt);
        L = pt.beta * scatter(pt, ls.wi, false) * sampled.beta;
        if (is_black(L)) return false;
        return visibility(pt, sampled);
    }
    const PathVertex& qs = light[s - 1];
    const PathVertex& pt = camera[t - 1];
    if (!connectible(qs) || !connectible(pt)) return false;
    Vec3 w = pt.p - qs.p;
    float d2 = length_squared(w);
    if (!(d2 > 0.f)) return false;
    w = w / std::sqrt(d2);
    L = qs.beta * scatter(qs, w, true) * scatter(pt, -w, false) * pt.beta * (1.f / d2);
    if (is_black(L)) return false;
    return visibility(qs, pt);
}

Spectrum BdptTracer::finish_connect(BdptConnection& k, float tr, float pass_pdf,
                                    Vec2* p_raster) const {
    if (!(tr > 0.f)) return k.result = Spectrum(0.f);
    k.L *= tr;
    if (k.t == 1) *p_raster = k.p_raster;
    return k.result = connect_tail(k, pass_pdf);
}

Spectrum BdptTracer::connect_tail(BdptConnection& k, float conn_pass_pdf) const {
    k.tail = true;
    Spectrum L = k.L;
    if (is_black(L)) return L;
    const int s = k.s, t = k.t;
    if (m_scene.has_pass_through()) {
        // The subpath ends used here exist only with their walks' scattering probability
        // (a walk may cross such a surface instead): divide it out (see mis_weight).
        float e = 1.f;
        if (s > 1) e *= scatter_probability(k.light[s - 1], k.light[s - 2]);
        if (t > 1) e *= scatter_probability(k.camera[t - 1], k.camera[t - 2]);
        if (!(e > 0.f)) return Spectrum(0.f);
        L /= e;
    }
    float w = k.mis ? mis_weight(k.light, s, k.camera, t, k.sampled, conn_pass_pdf) : 1.f;
    return L * w;
}

Spectrum BdptTracer::connect(const PathVertex* light, int s, const PathVertex* camera, int t,
                             BdptSampler& sampler, Vec2* p_raster, bool mis, BdptCounters& c,
                             PathVertex* sampled_out) const {
    BdptConnection k;
    Spectrum L(0.f);
    if (begin_connect(light, s, camera, t, sampler, mis, c, k)) {
        float pass_pdf = 1.f;  // crossings of the connection segment (Scene::transmittance)
        const float tr = m_scene.transmittance(k.shadow, &pass_pdf);
        L = finish_connect(k, tr, pass_pdf, p_raster);
    } else {
        L = k.result;
    }
    if (sampled_out && k.tail) *sampled_out = k.sampled;
    return L;
}

}  // namespace cmlt
