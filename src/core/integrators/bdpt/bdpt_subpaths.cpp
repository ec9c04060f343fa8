// BDPT subpaths: the random walks of the camera and light subpaths (scalar, and one
// ray query at a time for the resumable strategy); see bdpt_tracer.h.
#include "integrators/bdpt/bdpt_detail.h"
#include "integrators/bdpt/bdpt_tracer.h"

#include "materials/bsdf.h"
#include "materials/material_eval.h"
#include "math/frame.h"
#include "math/safe_math.h"
#include "sampling/warp.h"
#include "scene/scene.h"

#include <algorithm>
#include <cmath>
#include <optional>

namespace cmlt {

using bdpt_detail::leave_point;
using bdpt_detail::mode_of;

bool BdptTracer::begin_walk(BdptWalk& wk, const Ray& ray, const Spectrum& beta, float pdf_dir,
                            int max_vertices, bool importance, bool roulette, PathVertex* path,
                            int start) const {
    wk.ray = ray;
    wk.beta = beta;
    wk.rr_beta = Spectrum(1.f);
    wk.pdf_fwd_sa = pdf_dir;
    wk.pass_pdf = 1.f;
    wk.path = path;
    wk.n = start;
    wk.start = start;
    wk.max_vertices = max_vertices;
    wk.importance = importance;
    wk.roulette = roulette;
    return wk.n < max_vertices;
}

void BdptTracer::run_walk(BdptWalk& wk, BdptSampler& sampler, BdptCounters& c) const {
    for (;;) {
        if (!walk_step(wk, m_scene.intersect(wk.ray), sampler, c)) return;
    }
}

bool BdptTracer::walk_step(BdptWalk& wk, const SceneHit& hit, BdptSampler& sampler,
                           BdptCounters& c) const {
    const Scene& scene = m_scene;
    PathVertex* path = wk.path;
    int& n = wk.n;  // vertices so far (path[n - 1] is the previous one)
    const int start = wk.start, max_vertices = wk.max_vertices;
    const bool importance = wk.importance;
    Ray& ray = wk.ray;
    Spectrum& beta = wk.beta;
    Spectrum& rr_beta = wk.rr_beta;
    float& pdf_fwd_sa = wk.pdf_fwd_sa;
    // Pass-through crossings since path[n - 1] (cut-outs, ior-1 interfaces): not
    // vertices, but the walk reaches the next vertex only with the product of their
    // lobe probabilities, a factor of its density (and of the reverse density along the
    // same segment), as Scene::transmittance reports it for a connection.
    float& pass_pdf = wk.pass_pdf;
    // MIS densities are recomputed from the vertex positions (not the offset ray
    // directions), so that they are the same functions of the path whichever strategy
    // sampled it: `edge` is called once the next vertex along direction w is known.
    auto edge = [&](const Vec3& w) {
        PathVertex& prev = path[n - 1];
        if (n - 1 < start || prev.type != VertexType::surface || prev.delta || !prev.bsdf) return;
        float rev = 0.f;
        prev.bsdf->pdf_pair(prev.wo, w, &pdf_fwd_sa, &rev);
        path[n - 2].pdf_rev = convert_density(rev, prev, path[n - 2]) * prev.pass_pdf;
    };
    c.rays += 1;
    PathVertex& prev = path[n - 1];
    if (hit.kind == SceneHit::Kind::miss) {
        // Escaped: a direction vertex on the infinite lights (camera subpaths only).
        if (!importance && !scene.infinite_lights().empty()) {
            edge(normalize(ray.d));
            PathVertex& v = path[n];
            v.reset(VertexType::light);
            v.time = ray.time;
            v.infinite = true;
            v.w_inf = -normalize(ray.d);
            v.beta = beta;
            v.pdf_fwd = pdf_fwd_sa * pass_pdf;
            v.pass_pdf = pass_pdf;
            ++n;
        }
        return false;
    }
    if (hit.kind == SceneHit::Kind::light) {
        // Analytic emitters do not scatter; light subpaths end here.
        if (!importance) {
            Vec3 p_hit = ray.at(hit.t);
            Vec3 w = p_hit - prev.p;
            edge(length_squared(w) > 0.f ? normalize(w) : normalize(ray.d));
            PathVertex& v = path[n];
            v.reset(VertexType::light);
            v.time = ray.time;
            v.light_index = int32_t(hit.light_index);
            v.p = p_hit;
            v.ng = v.ns = scene.light(hit.light_index).emitter_normal(v.p);
            v.wo = -normalize(ray.d);
            v.error_scale = point_error_scale(v.p);
            v.le = hit.le;
            v.beta = beta;
            v.pdf_fwd = convert_density(pdf_fwd_sa, prev, v) * pass_pdf;
            v.pass_pdf = pass_pdf;
            ++n;
        }
        return false;
    }
    Vec3 w_in = hit.si.p - prev.p;
    if (prev.infinite || !(length_squared(w_in) > 0.f)) w_in = ray.d;
    w_in = normalize(w_in);
    const Material& mat = scene.material(hit.si.material_id);
    // A surface that may pass rays: sample its BSDF first (with the numbers the vertex
    // would use); the pass-through lobe crosses it without making a vertex.
    std::optional<Bsdf> pass_bsdf;
    bool sampled = false;
    BsdfSample bs;
    float u_rr = 0.f;
    if (scene.material_passes(hit.si.material_id)) {
        pass_bsdf.emplace(make_bsdf(mat, hit.si, scene.textures()));
        Vec2 u2 = sampler.next2d();
        float u1 = sampler.next1d();
        u_rr = sampler.next1d();
        bs = pass_bsdf->sample(-w_in, u2, u1, mode_of(importance));
        sampled = true;
        if (bs.valid() && bs.pass_through) {
            // T / p; for wi = -wo the importance correction of the shading normal is 1.
            Spectrum factor =
                bs.f * (std::fabs(dot(bs.wi, pass_bsdf->shading_normal())) / bs.pdf);
            beta *= factor;
            rr_beta *= factor;
            if (is_black(beta) || !is_finite(beta)) return false;
            pass_pdf *= bs.pdf;
            ray = hit.si.spawn_ray(bs.wi);
            return true;  // n < max_vertices still: no vertex was made
        }
    }
    edge(w_in);
    PathVertex& v = path[n];
    v.reset(VertexType::surface);
    v.time = ray.time;
    v.si = hit.si;
    v.p = hit.si.p;
    v.ng = hit.si.ng;
    v.wo = -w_in;
    v.si.wo = v.wo;
    v.error_scale = hit.si.error_scale;
    // The same textured BSDF as the path tracer (normal maps, cutouts, textures).
    if (pass_bsdf) v.bsdf = std::move(pass_bsdf);
    else v.bsdf.emplace(make_bsdf(mat, hit.si, scene.textures()));
    v.ns = v.bsdf->shading_normal();
    v.beta = beta;
    v.pdf_fwd = convert_density(pdf_fwd_sa, prev, v) * pass_pdf;
    v.pass_pdf = pass_pdf;
    pass_pdf = 1.f;
    if (!importance && mat.is_emissive()) {
        v.le = emitted_radiance(mat, hit.si.uv, scene.textures());
        v.light_index = scene.triangle_light_index(hit.si.instance_id, hit.si.prim_id);
    }
    ++n;
    if (n >= max_vertices) return false;

    // Sample the next direction (already done above on a surface that may pass rays).
    if (!sampled) {
        Vec2 u2 = sampler.next2d();
        float u1 = sampler.next1d();
        u_rr = sampler.next1d();
        bs = v.bsdf->sample(v.wo, u2, u1, mode_of(importance));
    }
    if (!bs.valid()) return false;
    pdf_fwd_sa = bs.pdf;  // replaced by edge() from positions unless Dirac
    if (bs.is_delta) {
        v.delta = true;
        pdf_fwd_sa = 0.f;
        prev.pdf_rev = 0.f;
    }
    Spectrum factor;
    if (!importance) {
        factor = bs.f * (std::fabs(dot(bs.wi, v.ns)) / bs.pdf);
    } else {
        float den = std::fabs(dot(v.wo, v.si.ng)) * bs.pdf;
        if (!(den > 0.f)) return false;
        factor = bs.f * (std::fabs(dot(v.wo, v.ns)) * std::fabs(dot(bs.wi, v.si.ng)) / den);
    }
    beta *= factor;
    rr_beta *= factor;
    if (is_black(beta) || !is_finite(beta)) return false;

    // Russian roulette on the scattering throughput.
    if (wk.roulette && n - start >= k_rr_start_depth) {
        float q = std::min(0.95f, max_component(rr_beta));
        if (!(u_rr < q)) return false;
        beta /= q;
        rr_beta /= q;
    }
    ray = v.si.spawn_ray(bs.wi);
    return true;
}

bool BdptTracer::begin_camera_subpath(const Vec2& p_raster, BdptSampler& sampler,
                                      int max_vertices, bool roulette, PathVertex* path,
                                      BdptCounters& c, BdptWalk& walk) const {
    walk.n = 0;
    if (max_vertices < 1) return false;
    const Camera& cam = m_importance.camera();
    // Motion blur: the sample's shutter time is the camera stream's next 1D, right after
    // the film position (drawn only when something moves, so a still scene keeps every
    // other number); the light subpath and the connections use it too.
    const float time = m_motion_blur ? sampler.next1d() : 0.f;
    // Thin lens: the lens position is the camera stream's next 2D (drawn only with a lens).
    Ray ray = cam.has_lens() ? cam.generate_ray(p_raster, sampler.next2d())
                             : cam.generate_ray(p_raster);
    ray.time = time;
    PathVertex& v = path[0];
    v.reset(VertexType::camera);
    v.time = time;
    v.p = ray.o;
    v.beta = Spectrum(1.f);
    v.pdf_fwd = 1.f;
    v.delta = !m_importance.connectable();
    walk.n = 1;
    if (max_vertices == 1) return false;
    c.camera_rays += 1;
    float pdf_dir = m_importance.pdf_dir(ray.o, ray.d);
    if (!(pdf_dir > 0.f)) pdf_dir = 1.f;  // edge of the image (float rounding)
    return begin_walk(walk, ray, Spectrum(1.f), pdf_dir, max_vertices, false, roulette, path, 1);
}

int BdptTracer::generate_camera_subpath(const Vec2& p_raster, BdptSampler& sampler,
                                        int max_vertices, bool roulette, PathVertex* path,
                                        BdptCounters& c) const {
    BdptWalk walk;
    if (begin_camera_subpath(p_raster, sampler, max_vertices, roulette, path, c, walk))
        run_walk(walk, sampler, c);
    return walk.n;
}

bool BdptTracer::begin_light_subpath(BdptSampler& sampler, int max_vertices, bool roulette,
                                     PathVertex* path, float time, BdptWalk& walk,
                                     float* disk_pdf_out) const {
    const Scene& scene = m_scene;
    walk.n = 0;
    *disk_pdf_out = 0.f;
    if (max_vertices < 1 || scene.light_count() == 0) return false;
    float u_light = sampler.next1d();
    Vec2 u_pos = sampler.next2d();
    Vec2 u_dir = sampler.next2d();
    float pmf = 0.f;
    size_t li = scene.sample_light(u_light, &pmf);
    if (!(pmf > 0.f)) return false;
    const Light& light = scene.light(li);
    PathVertex& v = path[0];
    v.reset(VertexType::light);
    v.time = time;
    v.light_index = int32_t(li);
    Ray ray;
    Spectrum beta;
    float pdf_dir = 0.f, disk_pdf = 0.f;
    if (light.is_infinite()) {
        // Direction from the light's own sampling, origin on a disk covering the scene.
        Vec3 center = scene.bounds_center();
        float r = scene.bounds_radius();
        LightSample ls = light.sample_li(center, u_dir);
        if (!ls.valid()) return false;
        Vec3 d = -ls.wi;
        Frame f(d);
        Vec2 dk = square_to_uniform_disk_concentric(u_pos);
        Vec3 o = center + (f.s * dk.x + f.t * dk.y - d) * r;
        disk_pdf = 1.f / (k_pi * r * r);
        v.infinite = true;
        v.w_inf = d;
        v.pdf_fwd = pmf * ls.pdf;
        v.beta = ls.li;
        pdf_dir = ls.pdf;
        beta = ls.li / (pmf * disk_pdf * ls.pdf);
        ray = Ray(o, d);
    } else {
        const bool guided = m_guided_lights && m_guided[li];
        LightLeSample les;
        if (!guided) {
            les = light.sample_le(u_pos, u_dir);
            if (!les.valid()) return false;
            pdf_dir = les.pdf_dir;
        } else {
            // the direction's first number picks the branch, then (rescaled) the caster
            const float g = m_guide_fraction;
            const float ux = u_dir.x;
            float own_dir = 0.f;
            if (ux < g) {
                les = emission_point(light, u_pos);
                if (!(les.pdf_pos > 0.f)) return false;
                les.d = m_guide.sample(les.p, Vec2(std::min(ux / g, k_one_minus_eps), u_dir.y));
                // a direction behind the emitting side: a vertex with no radiance (the
                // strategies with s = 1 sample their own light point and still count)
                if (!light.le_toward(les.p, les.d, &les.le)) les.le = Spectrum(0.f);
                float own_pos = 0.f;
                light.pdf_le(les.p, les.d, &own_pos, &own_dir);
            } else {
                les = light.sample_le(u_pos, Vec2(std::min((ux - g) / (1.f - g), k_one_minus_eps), u_dir.y));
                if (!les.valid()) return false;
                own_dir = les.pdf_dir;
            }
            pdf_dir = emission_pdf_dir(int32_t(li), les.p, les.d, own_dir);
        }
        v.p = les.p;
        v.ng = v.ns = les.n;
        v.error_scale = les.error_scale;
        v.pdf_fwd = pmf * les.pdf_pos;
        v.beta = les.le;
        float cos = is_black(les.n) ? 1.f : std::fabs(dot(les.n, les.d));
        beta = pdf_dir > 0.f ? les.le * (cos / (pmf * les.pdf_pos * pdf_dir)) : Spectrum(0.f);
        ray = Ray(leave_point(v, les.d), les.d);
    }
    ray.time = time;
    *disk_pdf_out = disk_pdf;
    walk.n = 1;
    if (max_vertices == 1) return false;
    if (is_black(beta) || !is_finite(beta)) return false;
    return begin_walk(walk, ray, beta, pdf_dir, max_vertices, true, roulette, path, 1);
}

void BdptTracer::end_light_subpath(PathVertex* path, int n, float disk_pdf) const {
    if (n < 2) return;
    const PathVertex& v = path[0];
    // From positions, times the crossings' probabilities on the way (pass_pdf).
    if (!v.infinite) {
        path[1].pdf_fwd = pdf_light(v, path[1]) * path[1].pass_pdf;
    } else {
        // The first surface vertex's density is the disk's (parallel rays).
        path[1].pdf_fwd = disk_pdf;
        if (path[1].on_surface()) path[1].pdf_fwd *= std::fabs(dot(path[1].ng, v.w_inf));
        path[1].pdf_fwd *= path[1].pass_pdf;
    }
}

int BdptTracer::generate_light_subpath(BdptSampler& sampler, int max_vertices, bool roulette,
                                       PathVertex* path, BdptCounters& c, float time) const {
    BdptWalk walk;
    float disk_pdf = 0.f;
    if (begin_light_subpath(sampler, max_vertices, roulette, path, time, walk, &disk_pdf))
        run_walk(walk, sampler, c);
    end_light_subpath(path, walk.n, disk_pdf);
    return walk.n;
}

}  // namespace cmlt
