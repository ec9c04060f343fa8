#include "analysis/scene_probes.h"

#include "cameras/camera.h"
#include "materials/bsdf.h"
#include "materials/material_eval.h"
#include "math/frame.h"
#include "sampling/discrete_distribution.h"
#include "sampling/rng.h"
#include "sampling/warp.h"
#include "util/error.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <sstream>
#include <string>
#include <unordered_set>
#include <vector>

namespace cmlt {

void ProbeOptions::validate() const {
    auto fail = [](const char* what) { CMLT_THROW(SettingsError, "probe_scene: " << what); };
    if (width < 1 || height < 1) fail("width and height must be >= 1");
    if (light_paths > (1u << 24) || targeted_paths > (1u << 24) || camera_paths > (1u << 24))
        fail("at most 2^24 paths of each kind");
    if (light_samples < 1 || light_samples > 64) fail("light_samples must be 1..64");
    if (max_chain < 1 || max_chain > 64) fail("max_chain must be 1..64");
    if (!(specular_roughness >= 0.f && specular_roughness <= 1.f))
        fail("specular_roughness must be in [0, 1]");
}

namespace {

/// Probe kinds: separate counter spaces of the Philox stream (the `sample` slot).
enum : uint32_t { k_probe_emitted = 1, k_probe_targeted = 2, k_probe_camera = 3 };

}  // namespace

/// Can the material be near-specular somewhere (constants, or the deciding inputs
/// textured / read from primvars): its triangles are targeted-probe candidates.
bool material_may_be_specular(const Material& m, float max_roughness) {
    if (!m.preview) return false;
    const bool rough_varies = m.tex_roughness >= 0 || m.pv_roughness >= 0;
    if (!(m.roughness < max_roughness) && !rough_varies) return false;
    const bool metal = !m.use_specular_workflow &&
                       (m.metallic >= 0.5f || m.tex_metallic >= 0 || m.pv_metallic >= 0);
    const bool mirror = m.use_specular_workflow &&
                        (max_component(m.specular) >= 0.5f || m.tex_specular >= 0 ||
                         m.pv_specular >= 0);
    const bool glass = std::fabs(m.ior - 1.f) >= 1e-3f && !(m.opacity_threshold > 0.f) &&
                       (m.opacity <= 0.5f || m.tex_opacity >= 0 || m.pv_opacity >= 0);
    return metal || mirror || glass;
}

bool scene_may_be_specular(const Scene& scene, float max_roughness) {
    for (size_t k = 0; k < scene.material_count(); ++k)
        if (material_may_be_specular(scene.material(uint32_t(k)), max_roughness)) return true;
    return false;
}

namespace {

/// The rule of the header, on the parameters at the hit.
bool near_specular(const PreviewSurfaceParams& p, float max_roughness) {
    if (!(p.roughness < max_roughness)) return false;
    if (!p.use_specular_workflow && p.metallic >= 0.5f) return true;
    if (p.use_specular_workflow && max_component(p.specular) >= 0.5f) return true;
    return (1.f - p.opacity) >= 0.5f && std::fabs(p.ior - 1.f) >= 1e-3f;
}

class Prober {
public:
    Prober(const Scene& scene, const ProbeOptions& o)
        : m_scene(scene), m_o(o), m_camera(scene.camera_desc(), o.width, o.height),
          m_cam_pos(m_camera.position()) {}

    ProbeResult run() {
        ProbeResult r;
        build_candidates(&r);
        visibility(&r);  // first: it finds the triangles seen through specular chains
        if (m_scene.light_count() > 0) {
            for (uint32_t i = 0; i < m_o.light_paths; ++i) emitted_path(i, &r);
            if (m_candidates.size() > 0)
                for (uint32_t i = 0; i < m_o.targeted_paths; ++i) targeted_path(i, &r);
        }
        if (r.light_paths > 0) {
            r.direct_flux /= double(m_o.light_paths);
            r.caustic_flux_emitted /= double(m_o.light_paths);
        }
        if (r.targeted_paths > 0) r.caustic_flux_targeted /= double(r.targeted_paths);
        return r;
    }

private:
    struct Candidate {
        uint32_t instance, prim;
    };

    bool is_specular(const SurfaceInteraction& si) const {
        const Material& mat = m_scene.material(si.material_id);
        if (!m_may_specular[si.material_id]) return false;
        return near_specular(preview_params(mat, si.uv, m_scene.textures(), si.primvars,
                                            si.n_primvars),
                             m_o.specular_roughness);
    }

    /// Triangles of near-specular candidate materials, by world area.
    void build_candidates(ProbeResult* r) {
        const size_t nm = m_scene.material_count();
        m_may_specular.assign(nm, 0);
        bool any = false;
        for (size_t k = 0; k < nm; ++k) {
            m_may_specular[k] = material_may_be_specular(m_scene.material(uint32_t(k)),
                                                m_o.specular_roughness);
            any = any || m_may_specular[k];
        }
        if (!any) return;
        std::vector<double> areas;
        for (uint32_t i = 0; i < m_scene.instance_count(); ++i) {
            const Instance& inst = m_scene.instance(i);
            const Mesh& mesh = m_scene.mesh(inst.mesh_id);
            for (uint32_t t = 0; t < mesh.data.n_tris; ++t) {
                const uint32_t mid = mesh.material_id(t);
                if (mid >= nm || !m_may_specular[mid]) continue;
                uint32_t v[3];
                mesh.triangle(t, v);
                Vec3 a = inst.xf.m.transform_point(mesh.point(v[0]));
                Vec3 b = inst.xf.m.transform_point(mesh.point(v[1]));
                Vec3 c = inst.xf.m.transform_point(mesh.point(v[2]));
                float area = 0.5f * length(cross(b - a, c - a));
                if (!(area > 0.f) || !std::isfinite(area)) continue;
                m_candidates.push_back({i, t});
                areas.push_back(double(area));
                r->candidate_area += double(area);
            }
        }
        if (!areas.empty()) m_candidate_dist = DiscreteDistribution(areas);
    }

    Vec3 world_point(const Candidate& c, const Vec2& u) const {
        const Instance& inst = m_scene.instance(c.instance);
        const Mesh& mesh = m_scene.mesh(inst.mesh_id);
        uint32_t v[3];
        mesh.triangle(c.prim, v);
        float su = std::sqrt(u.x);
        float b1 = 1.f - su, b2 = u.y * su;
        Vec3 p0 = mesh.point(v[0]), p1 = mesh.point(v[1]), p2 = mesh.point(v[2]);
        return inst.xf.m.transform_point(p0 * (1.f - b1 - b2) + p1 * b1 + p2 * b2);
    }

    /// (instance, triangle, side of the geometric normal) as one key.
    static uint64_t side_key(const SurfaceInteraction& si, bool front) {
        return (uint64_t(si.instance_id) << 33) | (uint64_t(si.prim_id) << 1) | (front ? 1u : 0u);
    }

    /// The camera sees `si` directly, on the side light arrives from (`w_in`, pointing
    /// away from the surface toward where the light came from).
    bool camera_sees(const SurfaceInteraction& si, const Vec3& w_in) const {
        if (!m_seen_via_specular.empty() &&
            m_seen_via_specular.count(side_key(si, dot(w_in, si.ng) >= 0.f)))
            return true;
        Vec2 raster;
        if (!m_camera.world_to_raster(si.p, &raster)) return false;
        if (!(raster.x >= 0.f && raster.y >= 0.f && raster.x < float(m_o.width) &&
              raster.y < float(m_o.height)))
            return false;
        Vec3 to_cam = m_cam_pos - si.p;
        if (dot(to_cam, si.ng) * dot(w_in, si.ng) <= 0.f) return false;
        float pass_pdf = 1.f;
        return m_scene.transmittance(si.spawn_ray_to(m_cam_pos), &pass_pdf) > 0.f;
    }

    /// Next scattering vertex along `ray`, stepping through pass-through crossings
    /// (taken with the BSDF's own probability, `beta` weighted by T / p). False on a miss,
    /// an analytic light, or a crossing not taken... then `si` is the vertex.
    bool next_vertex(Ray ray, PixelSampler& s, Spectrum* beta, SurfaceInteraction* si) const {
        for (int k = 0; k < k_max_pass_through_crossings; ++k) {
            SceneHit h = m_scene.intersect(ray);
            if (h.kind != SceneHit::Kind::surface) return false;
            *si = h.si;
            if (!m_scene.material_passes(si->material_id)) return true;
            Bsdf bsdf = make_bsdf(m_scene.material(si->material_id), *si, m_scene.textures());
            float prob = 0.f;
            float tr = bsdf.pass_through(si->wo, &prob);
            float u = s.get1d();
            if (!(prob > 0.f) || !(u < prob)) return true;
            *beta *= tr / prob;
            ray = si->spawn_ray(ray.d);
        }
        return false;
    }

    /// From a near-specular vertex `si` (reached by light travelling toward it), follow
    /// the chain; true and the diffuse end vertex in *end if it ends on a diffuse vertex
    /// the camera sees.
    bool follow_chain(SurfaceInteraction si, PixelSampler& s, Spectrum* beta,
                      SurfaceInteraction* end, TransportMode mode) const {
        for (int k = 0; k < m_o.max_chain; ++k) {
            Bsdf bsdf = make_bsdf(m_scene.material(si.material_id), si, m_scene.textures());
            Vec2 u2 = s.get2d();
            float u1 = s.get1d();
            BsdfSample bs = bsdf.sample(si.wo, u2, u1, mode);
            if (!bs.valid()) return false;
            *beta *= bs.f * (std::fabs(dot(bs.wi, bsdf.shading_normal())) / bs.pdf);
            if (is_black(*beta) || !is_finite(*beta)) return false;
            SurfaceInteraction next;
            if (!next_vertex(si.spawn_ray(bs.wi), s, beta, &next)) return false;
            if (!is_specular(next)) {
                *end = next;
                return true;
            }
            si = next;
        }
        return false;
    }

    void emitted_path(uint32_t i, ProbeResult* r) {
        PixelSampler s(m_o.seed, i, k_probe_emitted);
        float pmf = 0.f;
        size_t li = m_scene.sample_light(s.get1d(), &pmf);
        const Light& light = m_scene.light(li);
        Vec2 u_pos = s.get2d(), u_dir = s.get2d();
        Ray ray;
        Spectrum beta;
        if (light.is_infinite()) {
            // A direction from the light's own sampling, parallel rays over a disk
            // covering the scene (BDPT's emission of infinite lights).
            Vec3 c = m_scene.bounds_center();
            float rad = m_scene.bounds_radius();
            LightSample ls = light.sample_li(c, u_dir);
            if (!ls.valid() || !(pmf > 0.f)) return;
            Vec3 d = -ls.wi;
            Frame f(d);
            Vec2 dk = square_to_uniform_disk_concentric(u_pos);
            ray = Ray(c + (f.s * dk.x + f.t * dk.y - d) * rad, d);
            beta = ls.li * (k_pi * rad * rad / (pmf * ls.pdf));
        } else {
            LightLeSample les = light.sample_le(u_pos, u_dir);
            if (!les.valid() || !(pmf > 0.f)) return;
            float cos = is_black(les.n) ? 1.f : std::fabs(dot(les.n, les.d));
            beta = les.le * (cos / (pmf * les.pdf_pos * les.pdf_dir));
            Vec3 o = is_black(les.n) ? les.p
                                     : offset_ray_origin(les.p, les.n, les.error_scale, les.d);
            ray = Ray(o, les.d);
        }
        if (is_black(beta) || !is_finite(beta)) return;
        r->light_paths += 1;
        SurfaceInteraction si;
        if (!next_vertex(ray, s, &beta, &si)) return;
        if (!is_specular(si)) {
            if (camera_sees(si, si.wo)) r->direct_flux += double(luminance(beta));
            return;
        }
        r->light_hit_specular += 1;
        SurfaceInteraction end;
        if (follow_chain(si, s, &beta, &end, TransportMode::Importance) &&
            camera_sees(end, end.wo)) {
            r->light_caustics += 1;
            r->caustic_flux_emitted += double(luminance(beta));
        }
    }

    void targeted_path(uint32_t i, ProbeResult* r) {
        PixelSampler s(m_o.seed, i, k_probe_targeted);
        r->targeted_paths += 1;
        float cpmf = 0.f;
        size_t ci = m_candidate_dist.sample(s.get1d(), &cpmf);
        const Candidate& cand = m_candidates[ci];
        Vec3 p = world_point(cand, s.get2d());
        float pmf = 0.f;
        size_t li = m_scene.sample_light(s.get1d(), &pmf);
        const Light& light = m_scene.light(li);
        LightSample ls = light.sample_li(p, s.get2d());
        if (!ls.valid() || !(pmf > 0.f)) return;
        // The segment from the light toward p: its first hit must be the candidate.
        Ray ray;
        if (std::isinf(ls.dist)) {
            const float far = 2.f * m_scene.bounds_radius() + length(p - m_scene.bounds_center());
            ray = Ray(p + ls.wi * far, -ls.wi);
        } else {
            ray = Ray(shadow_target(ls.p_light, ls.n_light, ls.error_scale, ls.wi), -ls.wi);
        }
        SceneHit h = m_scene.intersect(ray);
        if (h.kind != SceneHit::Kind::surface || h.si.instance_id != cand.instance ||
            h.si.prim_id != cand.prim || !is_specular(h.si))
            return;
        r->targeted_reached += 1;
        // Flux onto the candidates: L cos / (pmf pdf) over the area density 1 / A
        // (triangle by area, then uniform on it).
        const float area_pdf = float(1.0 / r->candidate_area);
        const float cos_p = std::fabs(dot(h.si.ng, ls.wi));
        Spectrum beta = ls.li * (cos_p / (pmf * ls.pdf * area_pdf));
        if (is_black(beta) || !is_finite(beta)) return;
        SurfaceInteraction end;
        if (follow_chain(h.si, s, &beta, &end, TransportMode::Importance) &&
            camera_sees(end, end.wo)) {
            r->targeted_caustics += 1;
            r->caustic_flux_targeted += double(luminance(beta));
        }
    }

    /// Light samples at `si` that reach a light on the side of `si.wo`. `irradiance`:
    /// their mean estimate of the luminance irradiance at si (Le |cos| / (pmf pdf),
    /// visible samples only); `toward`: when given, their mean estimate of the radiance
    /// si scatters toward it instead (the BSDF at si from wo = toward).
    uint32_t lit_samples(const SurfaceInteraction& si, PixelSampler& s, double* irradiance = nullptr,
                         const Vec3* toward = nullptr) const {
        uint32_t lit = 0;
        if (irradiance) *irradiance = 0.0;
        if (m_scene.light_count() == 0) return 0;
        std::optional<Bsdf> bsdf;
        if (irradiance && toward) bsdf.emplace(make_bsdf(m_scene.material(si.material_id), si, m_scene.textures()));
        for (uint32_t j = 0; j < m_o.light_samples; ++j) {
            float pmf = 0.f;
            size_t li = m_scene.sample_light(s.get1d(), &pmf);
            LightSample ls = m_scene.light(li).sample_li(si.p, s.get2d());
            if (!ls.valid() || !(pmf > 0.f)) continue;
            if (dot(ls.wi, si.ng) * dot(si.wo, si.ng) <= 0.f) continue;
            Ray shadow;
            if (std::isinf(ls.dist)) {
                shadow = si.spawn_ray(ls.wi);
            } else {
                shadow = si.spawn_ray_to(shadow_target(ls.p_light, ls.n_light, ls.error_scale, ls.wi));
            }
            float pass_pdf = 1.f;
            const float tr = m_scene.transmittance(shadow, &pass_pdf);
            if (!(tr > 0.f)) continue;
            ++lit;
            if (!irradiance) continue;
            Spectrum e = ls.li * (tr * std::fabs(dot(ls.wi, si.ng)) / (pmf * ls.pdf));
            if (bsdf) e = e * bsdf->eval(*toward, ls.wi, TransportMode::Radiance);
            const double y = double(luminance(e));
            if (std::isfinite(y) && y > 0.0) *irradiance += y;
        }
        if (irradiance) *irradiance /= double(m_o.light_samples);
        return lit;
    }

    /// Cosine-sampled bounces per camera diffuse hit for the indirect estimate (the
    /// relative variance of a heavy-tailed estimate wants many: 256 hits x 8).
    static constexpr int k_indirect_bounces = 8;

    void visibility(ProbeResult* r) {
        const uint32_t n = m_o.camera_paths;
        if (n == 0) return;
        // a stratified grid of about n cells over the image, jittered
        const float aspect = float(m_o.width) / float(m_o.height);
        uint32_t nx = std::max(1u, uint32_t(std::lround(std::sqrt(float(n) * aspect))));
        uint32_t ny = std::max(1u, (n + nx - 1) / nx);
        uint64_t lit1 = 0, lit2 = 0, tried2 = 0, lit_hits = 0;
        double sum_d = 0.0, sum_i = 0.0, sum_i2 = 0.0;
        for (uint32_t i = 0; i < n; ++i) {
            PixelSampler s(m_o.seed, i, k_probe_camera);
            Vec2 j = s.get2d();
            float fx = (float(i % nx) + j.x) / float(nx);
            float fy = (float((i / nx) % ny) + j.y) / float(ny);
            Ray ray = m_camera.generate_ray(Vec2(fx * float(m_o.width), fy * float(m_o.height)));
            r->camera_paths += 1;
            Spectrum beta(1.f);
            SurfaceInteraction si;
            if (!next_vertex(ray, s, &beta, &si)) {
                r->camera_escaped += 1;
                continue;
            }
            if (is_specular(si)) {
                SurfaceInteraction end;
                bool found = false;
                for (int k = 0; k < m_o.max_chain && !found; ++k) {
                    Bsdf bsdf = make_bsdf(m_scene.material(si.material_id), si, m_scene.textures());
                    Vec2 u2 = s.get2d();
                    BsdfSample bs = bsdf.sample(si.wo, u2, s.get1d());
                    if (!bs.valid()) break;
                    if (!next_vertex(si.spawn_ray(bs.wi), s, &beta, &end)) break;
                    if (is_specular(end)) si = end;
                    else found = true;
                }
                if (!found) {
                    r->camera_escaped += 1;
                    continue;
                }
                si = end;
                r->camera_specular_first += 1;
                m_seen_via_specular.insert(side_key(si, dot(si.wo, si.ng) >= 0.f));
            }
            r->camera_diffuse_hits += 1;
            double d1 = 0.0;
            uint32_t l1 = lit_samples(si, s, &d1);
            sum_d += d1;
            lit1 += l1;
            if (l1 > 0) ++lit_hits;
            // diffuse bounces on the side of wo: the first gives bounce_visible (and its
            // random numbers are drawn first, as before the others existed), all of them
            // the one-bounce indirect estimate (an escaped bounce counts 0)
            Frame f(dot(si.wo, si.ng) >= 0.f ? si.ng : -si.ng);
            for (int b = 0; b < k_indirect_bounces; ++b) {
                Vec3 d = f.to_world(square_to_cosine_hemisphere(s.get2d()));
                SurfaceInteraction x2;
                Spectrum b2(1.f);
                if (!next_vertex(si.spawn_ray(d), s, &b2, &x2)) continue;
                double l2 = 0.0;
                const Vec3 back = -d;
                const uint32_t l = lit_samples(x2, s, &l2, &back);
                if (b == 0) {
                    tried2 += 1;
                    lit2 += l;
                }
                // cosine-sampled bounce: irradiance = π E[radiance], through b2's crossings
                const double i1 = k_pi * l2 * double(luminance(b2));
                if (std::isfinite(i1) && i1 > 0.0) {
                    sum_i += i1;
                    sum_i2 += i1 * i1;
                }
            }
        }
        const double m = double(m_o.light_samples);
        if (r->camera_diffuse_hits > 0) {
            r->direct_visible = float(double(lit1) / (m * r->camera_diffuse_hits));
            r->lit_hits = float(double(lit_hits) / r->camera_diffuse_hits);
        }
        if (tried2 > 0) r->bounce_visible = float(double(lit2) / (m * double(tried2)));
        if (r->camera_diffuse_hits > 0) {
            const double hits = double(r->camera_diffuse_hits), bounces = hits * k_indirect_bounces;
            r->direct_irradiance = sum_d / hits;
            r->indirect_irradiance = sum_i / bounces;
            if (sum_i > 0.0) r->indirect_rel_var = bounces * sum_i2 / (sum_i * sum_i) - 1.0;
        }
    }

    const Scene& m_scene;
    const ProbeOptions& m_o;
    Camera m_camera;
    Vec3 m_cam_pos;
    std::vector<uint8_t> m_may_specular;
    /// Sides of triangles a camera probe reached through a specular chain (visibility()):
    /// the camera sees them, though not directly.
    std::unordered_set<uint64_t> m_seen_via_specular;
    std::vector<Candidate> m_candidates;
    DiscreteDistribution m_candidate_dist;
};

}  // namespace

ProbeResult probe_scene(const Scene& scene, const ProbeOptions& options) {
    options.validate();
    if (scene.dirty()) CMLT_THROW(SceneError, "probe_scene: commit() the scene first");
    if (!scene.has_camera()) CMLT_THROW(SceneError, "probe_scene: the scene has no camera");
    return Prober(scene, options).run();
}

}  // namespace cmlt
