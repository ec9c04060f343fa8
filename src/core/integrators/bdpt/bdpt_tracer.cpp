#include "integrators/bdpt/bdpt_tracer.h"

#include "materials/bsdf.h"
#include "materials/material_eval.h"
#include "materials/preview_surface.h"
#include "math/frame.h"
#include "math/safe_math.h"
#include "sampling/warp.h"
#include "scene/scene.h"
#include "util/error.h"

#include <algorithm>
#include <cmath>

namespace cmlt {

namespace {

// The BSDF's transport mode argument, where the Bsdf in this build takes one (it
// matters for refraction only); otherwise the symmetric two-argument call.
template <class B>
auto bsdf_eval(const B& b, const Vec3& wo, const Vec3& wi, TransportMode m, int)
    -> decltype(b.eval(wo, wi, m)) {
    return b.eval(wo, wi, m);
}
template <class B>
Spectrum bsdf_eval(const B& b, const Vec3& wo, const Vec3& wi, TransportMode, long) {
    return b.eval(wo, wi);
}
template <class B>
auto bsdf_sample(const B& b, const Vec3& wo, const Vec2& u2, float u1, TransportMode m, int)
    -> decltype(b.sample(wo, u2, u1, m)) {
    return b.sample(wo, u2, u1, m);
}
template <class B>
BsdfSample bsdf_sample(const B& b, const Vec3& wo, const Vec2& u2, float u1, TransportMode, long) {
    return b.sample(wo, u2, u1);
}

inline TransportMode mode_of(bool importance) {
    return importance ? TransportMode::Importance : TransportMode::Radiance;
}

inline float remap0(float f) { return f != 0.f ? f : 1.f; }

/// Origin of a ray leaving vertex v in direction w (offset off surfaces).
Vec3 leave_point(const PathVertex& v, const Vec3& w) {
    if (v.type == VertexType::surface) return offset_ray_origin(v.p, v.si.ng, v.si.error_scale, w);
    if (v.on_surface()) return offset_ray_origin(v.p, v.ng, v.error_scale, w);
    return v.p;
}

}  // namespace

// ---- camera importance --------------------------------------------------------------------

CameraImportance::CameraImportance(const Camera& camera, int width, int height)
    : m_camera(camera), m_width(width), m_height(height) {
    const CameraDesc& d = camera.desc();
    m_perspective = d.projection == CameraDesc::Projection::perspective;
    m_lens = m_perspective && camera.has_lens();
    m_fwd = normalize(d.transform.transform_vector(Vec3(0.f, 0.f, -1.f)));
    // Image window at distance 1 (see cameras/camera.h for the framing).
    float fl = d.focal_length;
    float ww = d.horizontal_aperture / fl;
    float wh = d.horizontal_aperture * float(height) / float(width) / fl;
    m_area = ww * wh;
    if (m_lens) {
        const float r = camera.lens_radius();
        m_pdf_lens = 1.f / (k_pi * r * r);
    }
}

bool CameraImportance::raster_of(const Vec3& p_lens, const Vec3& w, Vec2* p_raster) const {
    if (!(dot(w, m_fwd) > 0.f)) return false;
    if (!m_camera.lens_ray_to_raster(p_lens, w, p_raster)) return false;
    return p_raster->x >= 0.f && p_raster->x < float(m_width) && p_raster->y >= 0.f &&
           p_raster->y < float(m_height);
}

float CameraImportance::pdf_dir(const Vec3& p_lens, const Vec3& w) const {
    if (!m_perspective) return 1.f;  // Dirac direction: cancels in every weight (no t = 1)
    Vec2 pr;
    if (!raster_of(p_lens, w, &pr)) return 0.f;
    float c = dot(w, m_fwd);
    return 1.f / (m_area * c * c * c);
}

float CameraImportance::we(const Vec3& p_lens, const Vec3& w, Vec2* p_raster) const {
    if (!m_perspective) return 0.f;
    if (!raster_of(p_lens, w, p_raster)) return 0.f;
    float c = dot(w, m_fwd);
    float c2 = c * c;
    // Per unit lens area with a lens (times the lens density 1 / A_lens); the pinhole's
    // Dirac position has pdf_lens() = 1.
    return m_pdf_lens / (m_area * c2 * c2);
}

// ---- tracer ---------------------------------------------------------------------------------

BdptTracer::BdptTracer(const Scene& scene, const Camera& camera, int width, int height,
                       int max_depth)
    : m_scene(scene), m_importance(camera, width, height), m_width(width), m_height(height),
      m_max_depth(max_depth), m_motion_blur(scene.motion_blur()) {}

float BdptTracer::choose_strategy(int depth, float u, int* s, int* t) {
    if (depth == 0) {
        *s = 0;
        *t = 2;
        return 1.f;
    }
    int n = depth + 2;
    int k = std::min(int(u * float(n)), n - 1);
    // Skip (1, 1) (only exists at depth 0).
    *s = k;
    *t = n - k;
    return 1.f / float(n);
}

bool BdptTracer::is_delta_light(const PathVertex& v) const {
    return v.light_index >= 0 && m_scene.light(size_t(v.light_index)).is_delta();
}

bool BdptTracer::connectible(const PathVertex& v) const {
    switch (v.type) {
        case VertexType::surface: return v.bsdf && v.bsdf->has_non_delta();
        case VertexType::camera: return m_importance.connectable();
        case VertexType::light: return true;
    }
    return false;
}

float BdptTracer::convert_density(float pdf_sa, const PathVertex& from, const PathVertex& to) const {
    if (to.infinite) return pdf_sa;
    Vec3 w = to.p - from.p;
    float d2 = length_squared(w);
    if (!(d2 > 0.f)) return 0.f;
    float pdf = pdf_sa / d2;
    if (to.on_surface()) pdf *= std::fabs(dot(to.ng, w)) / std::sqrt(d2);
    return pdf;
}

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
    float pdf = pdf_dir / d2;
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

Spectrum BdptTracer::scatter(const PathVertex& v, const Vec3& w, bool importance) const {
    if (v.type != VertexType::surface || !v.bsdf) return Spectrum(0.f);
    const Bsdf& b = *v.bsdf;
    Spectrum f = bsdf_eval(b, v.wo, w, mode_of(importance), 0);
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

// ---- subpaths -------------------------------------------------------------------------------

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
        pdf_fwd_sa = prev.bsdf->pdf(prev.wo, w);
        path[n - 2].pdf_rev =
            convert_density(prev.bsdf->pdf(w, prev.wo), prev, path[n - 2]) * prev.pass_pdf;
    };
    c.rays += 1;
    PathVertex& prev = path[n - 1];
    if (hit.kind == SceneHit::Kind::miss) {
        // Escaped: a direction vertex on the infinite lights (camera subpaths only).
        if (!importance && !scene.infinite_lights().empty()) {
            edge(normalize(ray.d));
            PathVertex& v = path[n];
            v = PathVertex();
            v.type = VertexType::light;
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
            v = PathVertex();
            v.type = VertexType::light;
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
        bs = bsdf_sample(*pass_bsdf, -w_in, u2, u1, mode_of(importance), 0);
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
    v = PathVertex();
    v.type = VertexType::surface;
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
        bs = bsdf_sample(*v.bsdf, v.wo, u2, u1, mode_of(importance), 0);
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
    v = PathVertex();
    v.type = VertexType::camera;
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
    v = PathVertex();
    v.type = VertexType::light;
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
        LightLeSample les = light.sample_le(u_pos, u_dir);
        if (!les.valid()) return false;
        v.p = les.p;
        v.ng = v.ns = les.n;
        v.error_scale = les.error_scale;
        v.pdf_fwd = pmf * les.pdf_pos;
        v.beta = les.le;
        float cos = is_black(les.n) ? 1.f : std::fabs(dot(les.n, les.d));
        beta = les.le * (cos / (pmf * les.pdf_pos * les.pdf_dir));
        pdf_dir = les.pdf_dir;
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

// ---- connections and MIS -------------------------------------------------------------------

float BdptTracer::mis_weight(const PathVertex* light, int s, const PathVertex* camera, int t,
                             const PathVertex& sampled, float conn_pass_pdf,
                             const PathVertex* pt_override) const {
    const int n = s + t;
    if (n == 2) return 1.f;
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
            x[i] = (s == 1 && i == 0) ? &sampled : &light[i];
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
    pl[s] = s > 0 ? pdf(qs_minus, *qs, *pt) * conn_pass_pdf : pdf_light_origin(*pt, *pt_minus);
    if (pt_minus)
        pl[s + 1] = (s > 0 ? pdf(qs, *pt, *pt_minus) : pdf_light(*pt, *pt_minus)) * pt->pass_pdf;
    if (qs) pe[s - 1] = pdf(pt_minus, *pt, *qs) * conn_pass_pdf;
    if (qs_minus) pe[s - 2] = pdf(pt, *qs, *qs_minus) * qs->pass_pdf;
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
        sampled = PathVertex();
        sampled.type = VertexType::camera;
        sampled.time = qs.time;
        sampled.p = p_lens;
        sampled.beta = Spectrum(1.f);
        // We G / p_lens, G = cos_cam / d2 (the lens point has no cosine at qs's end
        // beyond scatter's): the lens density cancels We's 1 / A_lens.
        const float cos_cam = m_importance.cos_axis(-w);
        L = qs.beta * scatter(qs, w, true) * (we * cos_cam / (d2 * m_importance.pdf_lens()));
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
        sampled = PathVertex();
        sampled.type = VertexType::light;
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

// ---- estimators -----------------------------------------------------------------------------

Spectrum BdptTracer::li(const Vec2& p_raster, BdptSampler& sampler, BdptWorkspace& ws,
                        BdptCounters& c) const {
    const int max_cam = m_max_depth + 2, max_light = m_max_depth + 1;
    if (int(ws.camera.size()) < max_cam) ws.camera.resize(size_t(max_cam));
    if (int(ws.light.size()) < max_light) ws.light.resize(size_t(max_light));
    c.samples += 1;
    sampler.start_stream(BdptSampler::k_camera);
    int nc = generate_camera_subpath(p_raster, sampler, max_cam, true, ws.camera.data(), c);
    sampler.start_stream(BdptSampler::k_light);
    const float time = nc > 0 ? ws.camera[0].time : 0.f;  // the sample's shutter time
    int nl = generate_light_subpath(sampler, max_light, true, ws.light.data(), c, time);
    sampler.start_stream(BdptSampler::k_connection);
    Spectrum L(0.f);
    for (int t = 1; t <= nc; ++t) {
        for (int s = 0; s <= nl; ++s) {
            int depth = s + t - 2;
            if ((s == 1 && t == 1) || depth < 0 || depth > m_max_depth) continue;
            Vec2 pr;
            Spectrum lp = connect(ws.light.data(), s, ws.camera.data(), t, sampler, &pr, true, c);
            if (is_black(lp)) continue;
            if (t == 1) {
                ws.splats.push_back({pr, lp});
                c.splats += 1;
            } else {
                L += lp;
            }
        }
    }
    return L;
}

static Spectrum evaluate_one(const BdptTracer& tr, int width, int height, int depth, int s, int t,
                             BdptSampler& sampler, BdptWorkspace& ws, Vec2* p_raster,
                             bool mis, BdptCounters& c) {
    if (t < 1 || s < 0 || s + t != depth + 2 || (s == 1 && t == 1)) return Spectrum(0.f);
    if (int(ws.camera.size()) < t) ws.camera.resize(size_t(t));
    if (int(ws.light.size()) < std::max(s, 1)) ws.light.resize(size_t(std::max(s, 1)));
    c.samples += 1;
    sampler.start_stream(BdptSampler::k_camera);
    Vec2 u = sampler.next2d();
    *p_raster = Vec2(u.x * float(width), u.y * float(height));
    if (tr.generate_camera_subpath(*p_raster, sampler, t, false, ws.camera.data(), c) != t)
        return Spectrum(0.f);
    sampler.start_stream(BdptSampler::k_light);
    if (s > 0 && tr.generate_light_subpath(sampler, s, false, ws.light.data(), c,
                                           ws.camera[0].time) != s)
        return Spectrum(0.f);
    sampler.start_stream(BdptSampler::k_connection);
    return tr.connect(ws.light.data(), s, ws.camera.data(), t, sampler, p_raster, mis, c);
}

Spectrum BdptTracer::evaluate_strategy(int depth, int s, int t, BdptSampler& sampler,
                                       BdptWorkspace& ws, Vec2* p_raster, BdptCounters& c) const {
    return evaluate_one(*this, m_width, m_height, depth, s, t, sampler, ws, p_raster, true, c);
}

Spectrum BdptTracer::evaluate_strategy_unweighted(int depth, int s, int t, BdptSampler& sampler,
                                                  BdptWorkspace& ws, Vec2* p_raster,
                                                  BdptCounters& c) const {
    return evaluate_one(*this, m_width, m_height, depth, s, t, sampler, ws, p_raster, false, c);
}

// ---- the resumable strategy (BdptStrategyLane): evaluate_one, one query at a time ----------

BdptQuery BdptTracer::begin_strategy(BdptStrategyLane& lane, int depth, int s, int t,
                                     BdptSampler& sampler, BdptWorkspace& ws) const {
    lane.depth = depth;
    lane.s = s;
    lane.t = t;
    lane.sampler = &sampler;
    lane.ws = &ws;
    lane.result = Spectrum(0.f);
    lane.p_raster = Vec2();  // as evaluate_strategy's caller's, for a technique it rejects
    lane.counters = BdptCounters();
    lane.stage = BdptStrategyLane::Stage::done;
    if (t < 1 || s < 0 || s + t != depth + 2 || (s == 1 && t == 1)) return BdptQuery::none;
    if (int(ws.camera.size()) < t) ws.camera.resize(size_t(t));
    if (int(ws.light.size()) < std::max(s, 1)) ws.light.resize(size_t(std::max(s, 1)));
    lane.counters.samples += 1;
    sampler.start_stream(BdptSampler::k_camera);
    const Vec2 u = sampler.next2d();
    lane.p_raster = Vec2(u.x * float(m_width), u.y * float(m_height));
    if (begin_camera_subpath(lane.p_raster, sampler, t, false, ws.camera.data(), lane.counters,
                             lane.walk)) {
        lane.stage = BdptStrategyLane::Stage::camera_walk;
        return BdptQuery::intersect;
    }
    return strategy_after_camera(lane);
}

BdptQuery BdptTracer::strategy_after_camera(BdptStrategyLane& lane) const {
    lane.stage = BdptStrategyLane::Stage::done;
    if (lane.walk.n != lane.t) return BdptQuery::none;
    BdptWorkspace& ws = *lane.ws;
    lane.sampler->start_stream(BdptSampler::k_light);
    if (lane.s > 0) {
        if (begin_light_subpath(*lane.sampler, lane.s, false, ws.light.data(), ws.camera[0].time,
                                lane.walk, &lane.light_disk_pdf)) {
            lane.stage = BdptStrategyLane::Stage::light_walk;
            return BdptQuery::intersect;
        }
        return strategy_after_light(lane);
    }
    return strategy_connect(lane);
}

BdptQuery BdptTracer::strategy_after_light(BdptStrategyLane& lane) const {
    lane.stage = BdptStrategyLane::Stage::done;
    end_light_subpath(lane.ws->light.data(), lane.walk.n, lane.light_disk_pdf);
    if (lane.walk.n != lane.s) return BdptQuery::none;
    return strategy_connect(lane);
}

BdptQuery BdptTracer::strategy_connect(BdptStrategyLane& lane) const {
    BdptWorkspace& ws = *lane.ws;
    lane.sampler->start_stream(BdptSampler::k_connection);
    if (begin_connect(ws.light.data(), lane.s, ws.camera.data(), lane.t, *lane.sampler, true,
                      lane.counters, lane.conn)) {
        lane.stage = BdptStrategyLane::Stage::connection;
        return BdptQuery::visibility;
    }
    lane.result = lane.conn.result;
    lane.stage = BdptStrategyLane::Stage::done;
    return BdptQuery::none;
}

BdptQuery BdptTracer::resume_strategy(BdptStrategyLane& lane, const SceneHit& hit) const {
    CMLT_DCHECK(lane.stage == BdptStrategyLane::Stage::camera_walk ||
                lane.stage == BdptStrategyLane::Stage::light_walk);
    if (walk_step(lane.walk, hit, *lane.sampler, lane.counters)) return BdptQuery::intersect;
    return lane.stage == BdptStrategyLane::Stage::camera_walk ? strategy_after_camera(lane)
                                                             : strategy_after_light(lane);
}

BdptQuery BdptTracer::resume_strategy(BdptStrategyLane& lane, float transmittance,
                                      float pass_pdf) const {
    CMLT_DCHECK(lane.stage == BdptStrategyLane::Stage::connection);
    lane.result = finish_connect(lane.conn, transmittance, pass_pdf, &lane.p_raster);
    lane.stage = BdptStrategyLane::Stage::done;
    return BdptQuery::none;
}

std::vector<float> BdptTracer::strategy_weights(const PathVertex* light, int s,
                                                const PathVertex* camera, int t,
                                                const PathVertex& sampled,
                                                float* weight_here) const {
    const int n = s + t;
    // The whole path, light end first.
    std::vector<PathVertex> x(static_cast<size_t>(n));
    for (int i = 0; i < s; ++i) x[size_t(i)] = (s == 1) ? sampled : light[i];
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
        bool ok = !(sp == 1 && tp == 1);
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
        const PathVertex& samp = sp == 1 ? L[0] : (tp == 1 ? C[0] : sampled);
        weights[size_t(sp)] =
            mis_weight(L.data(), sp, C.data(), tp, samp, sp > 0 ? seg[size_t(sp - 1)] : 1.f);
    }
    return weights;
}

}  // namespace cmlt
