// Ray queries of the render scene: closest hits resolved to surfaces and analytic
// lights, surface interactions (placed by the instance's transform at the ray's time),
// and the visibility of shadow rays through pass-through surfaces; see scene.h. The
// building of the scene (meshes, instances, materials, lights, commit) is in scene.cpp.
#include "scene/scene.h"

#include "lights/area_lights.h"
#include "lights/cylinder_light.h"
#include "lights/infinite_lights.h"
#include "lights/sphere_light.h"
#include "materials/material_eval.h"
#include "util/error.h"

#include <algorithm>
#include <cmath>

namespace cmlt {

namespace {

/// A mesh hit's triangle placed in world space (vertices p0..p2, barycentrics b0..b2,
/// vertex indices v) and its surface geometry, as fill_interaction reports it.
struct PlacedTriangle {
    Vec3 p0, p1, p2;
    float b0, b1, b2;
    uint32_t v[3];
};

/// Places the triangle of `hit` by `xf` (or reads it from `placed`, the mesh's points
/// already placed by xf: Scene::m_placed, the same floats) and computes the geometry:
/// point, geometric and shading normal, direction to the ray origin, offset scale.
void place_triangle(const Ray& ray, const Hit& hit, const Mesh& mesh, const Transform& xf, const float* placed,
                    PlacedTriangle* tri, HitGeometry* g) {
    mesh.triangle(hit.prim_id, tri->v);
    const uint32_t* v = tri->v;
    Vec3 &p0 = tri->p0, &p1 = tri->p1, &p2 = tri->p2;
    if (placed) {
        const float *w0 = placed + 3 * size_t(v[0]), *w1 = placed + 3 * size_t(v[1]),
                    *w2 = placed + 3 * size_t(v[2]);
        p0 = Vec3(w0[0], w0[1], w0[2]);
        p1 = Vec3(w1[0], w1[1], w1[2]);
        p2 = Vec3(w2[0], w2[1], w2[2]);
    } else {
        // xf.m is affine (Transform checks it) and mesh points are finite (add_mesh checks)
        p0 = xf.m.transform_affine_point(mesh.point(v[0]));
        p1 = xf.m.transform_affine_point(mesh.point(v[1]));
        p2 = xf.m.transform_affine_point(mesh.point(v[2]));
    }
    const float b1 = hit.u, b2 = hit.v, b0 = 1.f - b1 - b2;
    tri->b0 = b0;
    tri->b1 = b1;
    tri->b2 = b2;
    g->sp.time = ray.time;
    g->sp.p = p0 * b0 + p1 * b1 + p2 * b2;
    g->wo = -normalize(ray.d);
    Vec3 ng = normalize(cross(p1 - p0, p2 - p0));
    if (is_black(ng) || !is_finite(ng)) ng = g->wo;  // degenerate triangle: face the ray
    g->sp.ng = ng;
    g->ns = ng;
    if (mesh.data.normals) {
        Vec3 n = mesh.normal(v[0]) * b0 + mesh.normal(v[1]) * b1 + mesh.normal(v[2]) * b2;
        n = normalize(xf.normal.transform_normal(n));
        if (!is_black(n) && is_finite(n)) g->ns = face_forward(n, ng);
    }
    g->sp.error_scale = max_component(vmax(vabs(p0), vmax(vabs(p1), vabs(p2))));
    g->material_id = mesh.material_id(hit.prim_id);
}

/// Scene::fill_interaction for the triangle of `hit` (place_triangle's arguments).
void fill_placed(const Ray& ray, const Hit& hit, const Instance& inst, const Mesh& mesh, const Transform& xf,
                 const float* placed, SurfaceInteraction* si) {
    PlacedTriangle tri;
    HitGeometry g;
    place_triangle(ray, hit, mesh, xf, placed, &tri, &g);
    static_cast<SurfacePoint&>(*si) = g.sp;
    si->ns = g.ns;
    si->wo = g.wo;
    si->t = hit.t;
    const uint32_t* v = tri.v;
    const float b0 = tri.b0, b1 = tri.b1, b2 = tri.b2;
    const float* const uvs = mesh.data.uvs;
    const float* const t[3] = {uvs ? uvs + 2 * size_t(v[0]) : nullptr, uvs ? uvs + 2 * size_t(v[1]) : nullptr,
                               uvs ? uvs + 2 * size_t(v[2]) : nullptr};
    si->uv = hit_uv(t, b0, b1, b2);
    if (uvs) {
        Vec2 t0 = mesh.uv(v[0]), t1 = mesh.uv(v[1]), t2 = mesh.uv(v[2]);
        // dp/du from the uv parametrisation of the triangle (pbrt's Triangle::Intersect).
        float du02 = t0.x - t2.x, du12 = t1.x - t2.x, dv02 = t0.y - t2.y, dv12 = t1.y - t2.y;
        float det = du02 * dv12 - dv02 * du12;
        si->dpdu = Vec3(0.f);
        if (std::fabs(det) > 1e-12f) {
            Vec3 d = ((tri.p0 - tri.p2) * dv12 - (tri.p1 - tri.p2) * dv02) * (1.f / det);
            if (is_finite(d)) si->dpdu = d;
        }
    } else {
        si->dpdu = Vec3(0.f);
    }
    si->instance_id = hit.instance_id;
    si->mesh_id = inst.mesh_id;
    si->prim_id = hit.prim_id;
    si->material_id = g.material_id;
    si->n_primvars = uint8_t(mesh.data.n_primvar_columns);
    if (si->n_primvars) {
        const float *q0 = mesh.primvar_row(v[0]), *q1 = mesh.primvar_row(v[1]),
                    *q2 = mesh.primvar_row(v[2]);
        for (int c = 0; c < si->n_primvars; ++c) si->primvars[c] = q0[c] * b0 + q1[c] * b1 + q2[c] * b2;
    }
}

}  // namespace

void Scene::fill_interaction(const Ray& ray, const Hit& hit, SurfaceInteraction* si) const {
    const Instance& inst = m_instances[hit.instance_id];
    const Mesh& mesh = m_meshes[inst.mesh_id];
    // A moving instance is placed where it is at the ray's time (as Embree placed it);
    // only then is a Transform built (a default-constructed one per hit showed in
    // profiles).
    if (inst.motion.size() > 1)
        fill_placed(ray, hit, inst, mesh, Transform(inst.matrix_at(ray.time), "moving instance"), nullptr, si);
    else
        fill_placed(ray, hit, inst, mesh, inst.xf,
                    m_placed[hit.instance_id].empty() ? nullptr : m_placed[hit.instance_id].data(), si);
}

void Scene::hit_geometry(const Ray& ray, const Hit& hit, HitGeometry* g) const {
    const Instance& inst = m_instances[hit.instance_id];
    const Mesh& mesh = m_meshes[inst.mesh_id];
    PlacedTriangle tri;
    if (inst.motion.size() > 1)
        place_triangle(ray, hit, mesh, Transform(inst.matrix_at(ray.time), "moving instance"), nullptr, &tri, g);
    else
        place_triangle(ray, hit, mesh, inst.xf,
                       m_placed[hit.instance_id].empty() ? nullptr : m_placed[hit.instance_id].data(), &tri, g);
}

bool Scene::triangle_corners(const Hit& hit, TriangleCorners* c) const {
    const CornerSource& s = m_corner_sources[hit.instance_id];
    if (s.moving) return false;
    const uint32_t* v = s.indices + 3 * size_t(hit.prim_id);
    for (int k = 0; k < 3; ++k) {
        if (s.placed) {
            const float* w = s.placed + 3 * size_t(v[k]);
            c->p[k] = Vec3(w[0], w[1], w[2]);
        } else {
            const float* q = s.points + 3 * size_t(v[k]);
            c->p[k] = s.xf->transform_affine_point(Vec3(q[0], q[1], q[2]));
        }
        c->n[k] = s.normals ? s.normals + 3 * size_t(v[k]) : nullptr;
        c->uv[k] = s.uvs ? s.uvs + 2 * size_t(v[k]) : nullptr;
    }
    c->primvars = s.primvars;
    c->normal = s.normals ? s.normal : nullptr;
    c->material_id = s.material_ids ? s.material_ids[hit.prim_id] : s.material_id_all;
    return true;
}

float Scene::nearest_light(const Ray& ray, float tmax, uint32_t* light_index, Spectrum* le) const {
    float t_best = k_infinity;
    for (size_t k = 0; k < m_analytic_area.size(); ++k) {
        if (!may_reach_light(ray, tmax, k)) continue;
        const uint32_t li = m_analytic_area[k];
        float t;
        Spectrum l;
        if (m_lights[li]->intersect(Ray(ray.o, ray.d, ray.tnear, tmax), &t, &l) && t < tmax) {
            tmax = t;
            t_best = t;
            *light_index = li;
            *le = l;
        }
    }
    return t_best;
}

bool Scene::intersect_surface(const Ray& ray, SurfaceInteraction* si) const {
    Hit h = m_accel->intersect(ray);
    if (!h.valid()) return false;
    fill_interaction(ray, h, si);
    return true;
}

bool Scene::may_reach_light(const Ray& ray, float tmax, size_t k) const {
    const AreaBound& b = m_area_bounds[k];
    if (!(b.r2 < k_infinity)) return true;
    // The distance from the centre to the segment, without a division (this test runs
    // for every camera and bounce ray): the nearest point of the line is at
    // t = s / dd (s = oc . d, dd = d . d); inside [tnear, tmax] the squared distance times
    // dd is cc dd - s^2 (cc = oc . oc), whose cancellation stays within ~1e-6 cc dd, so
    // the radius gets 4e-6 cc; outside, the nearer end's own distance, with a margin of
    // 1e-8 cc for the rounding of oc - d t.
    const Vec3 oc = b.center - ray.o;
    const float dd = dot(ray.d, ray.d), s = dot(oc, ray.d), cc = dot(oc, oc);
    float t;
    if (s < ray.tnear * dd) {
        t = ray.tnear;
    } else if (s > tmax * dd) {
        t = tmax;
    } else {
        return !(cc * dd - s * s > (b.r2 + 4e-6f * cc) * dd);  // NaN: test the light
    }
    const Vec3 q = oc - ray.d * t;
    return !(dot(q, q) > b.r2 + 1e-8f * cc);
}

bool Scene::blocked_by_light(const Ray& ray) const { return blocked_by_light(ray, k_no_light); }

bool Scene::blocked_by_light(const Ray& ray, size_t target) const {
    for (size_t k = 0; k < m_analytic_area.size(); ++k) {
        if (m_analytic_area[k] == target && m_area_bounds[k].planar) continue;
        if (!may_reach_light(ray, ray.tfar, k)) continue;
        float t;
        Spectrum le;
        if (m_lights[m_analytic_area[k]]->intersect(ray, &t, &le)) return true;
    }
    return false;
}

float Scene::transmittance(const Ray& shadow, size_t target, float* pass_pdf) const {
    *pass_pdf = 1.f;
    // An analytic emitter stops camera and BSDF rays (resolve_hit), so it stops shadow
    // rays and BDPT connections too: otherwise light tracing sees surfaces behind a lamp
    // that the camera cannot, and PT and BDPT disagree where a lamp is in view.
    if (m_light_proxies)
        return transmittance_given_lights(shadow, target, m_accel->occluded(shadow, true, shadow_skip_proxy(target)),
                                          pass_pdf);
    if (!m_analytic_area.empty() && blocked_by_light(shadow, target)) return 0.f;
    if (!m_accel->occluded(shadow)) return 1.f;
    return transmittance_through(shadow, pass_pdf);
}

float Scene::transmittance(const Ray& shadow, float* pass_pdf) const {
    return transmittance(shadow, k_no_light, pass_pdf);
}

float Scene::transmittance_through(const Ray& shadow, float* pass_pdf) const {
    if (!m_pass_through) return 0.f;
    // Something is in the way: walk the hits in order, crossing pass-through ones.
    Ray ray = shadow;
    float T = 1.f, P = 1.f;
    for (int k = 0; k < k_max_pass_through_crossings; ++k) {
        const Hit h = m_accel->intersect(ray);
        if (!h.valid()) {
            *pass_pdf = P;
            return T;
        }
        const Instance& inst = m_instances[h.instance_id];
        const uint32_t mid = m_meshes[inst.mesh_id].material_id(h.prim_id);
        if (!m_material_passes[mid]) return 0.f;
        SurfaceInteraction si;
        fill_interaction(ray, h, &si);
        const Bsdf bsdf = make_bsdf(m_materials[mid], si, m_textures);
        float p = 0.f;
        const float t = bsdf.pass_through(si.wo, &p);
        if (!(t > 0.f) || !(p > 0.f)) return 0.f;  // opaque here (e.g. above the cut-out threshold)
        T *= t;
        P *= p;
        // On from the far side of the surface, to the same end point.
        Ray next(offset_ray_origin(si.p, si.ng, si.error_scale, ray.d), ray.d, 0.f,
                 ray.tfar - h.t);
        next.time = ray.time;
        ray = next;
    }
    return 0.f;
}

bool Scene::AnalyticLightProxies::intersect(uint32_t k, const Ray& ray, float* t) const {
    Spectrum le;
    return m_scene.m_lights[m_scene.m_analytic_area[k]]->intersect(ray, t, &le);
}

SceneHit Scene::intersect(const Ray& ray) const { return resolve_hit(ray, m_accel->intersect(ray, m_light_proxies)); }

SceneHit Scene::resolve_hit(const Ray& ray, const Hit& h) const {
    SceneHit out;
    uint32_t li = 0;
    Spectrum le;
    float tl = k_infinity;
    if (h.light_hit()) {
        // The BVH's light proxy k was nearest: its radiance from the same test.
        li = m_analytic_area[h.light];
        float t;
        if (m_lights[li]->intersect(ray, &t, &le)) tl = t;
        CMLT_DCHECK(tl == h.t);
    } else if (h.light == k_lights_untested && !m_analytic_area.empty()) {
        // Analytic emitters the query did not test: test them and keep the nearest.
        tl = nearest_light(ray, h.valid() ? h.t : ray.tfar, &li, &le);
    }
    if (tl < k_infinity) {
        out.kind = SceneHit::Kind::light;
        out.light_index = li;
        out.le = le;
        out.t = tl;
        return out;
    }
    if (h.valid()) {
        out.kind = SceneHit::Kind::surface;
        out.t = h.t;
        fill_interaction(ray, h, &out.si);
    }
    return out;
}

}  // namespace cmlt
