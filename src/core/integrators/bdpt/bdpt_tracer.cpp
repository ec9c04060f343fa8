// BDPT estimators: every strategy of a pixel sample (li), one strategy of the
// Metropolis integrators (evaluate_strategy), and that strategy as a resumable
// computation (begin_strategy / resume_strategy); see bdpt_tracer.h. The subpaths,
// connections and MIS weights are in bdpt_subpaths.cpp, bdpt_connect.cpp, bdpt_mis.cpp.
#include "integrators/bdpt/bdpt_detail.h"
#include "integrators/bdpt/bdpt_tracer.h"

#include "scene/scene.h"
#include "util/error.h"

#include <algorithm>
#include <cmath>

namespace cmlt {

BdptTracer::BdptTracer(const Scene& scene, const Camera& camera, int width, int height,
                       int max_depth, float film_margin)
    : m_scene(scene), m_importance(camera, width, height, film_margin), m_width(width), m_height(height),
      m_margin(film_margin), m_max_depth(max_depth), m_motion_blur(scene.motion_blur()) {}

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
    // The connections of connect(), in three steps: every connection begun in the
    // scalar order (they draw their numbers in it), their shadow rays answered together
    // (Scene::transmittance split around the BVH query, as PathBatch does: analytic
    // lights, then Embree in packets, then pass-through surfaces), every connection
    // finished and summed in the same order.
    size_t n = 0;
    for (int t = 1; t <= nc; ++t)
        for (int s = 0; s <= nl; ++s) {
            const int depth = s + t - 2;
            if ((s == 1 && t == 1 && m_direct_light.empty()) || depth < 0 || depth > m_max_depth) continue;
            if (ws.conns.size() <= n) {
                ws.conns.resize(n + 1);
                ws.pending.resize(n + 1);
                ws.rays.resize(n + 1);
                ws.occluded.resize(n + 1);
            }
            ws.pending[n] = begin_connect(ws.light.data(), s, ws.camera.data(), t, sampler, true, c, ws.conns[n]);
            ++n;
        }
    // ws.occluded: 0 clear, 1 the BVH reports a hit, k_lamp stopped by an analytic light
    constexpr uint8_t k_lamp = 2;
    // With light proxies the BVH query tests the analytic lights too (no target skipped:
    // a connection ends at a vertex, not on a light).
    const bool proxies = m_scene.light_proxies();
    ws.queries.clear();
    for (size_t i = 0; i < n; ++i) {
        ws.occluded[i] = 0;
        if (!ws.pending[i]) continue;
        const Ray& shadow = ws.conns[i].shadow;
        if (!proxies && m_scene.has_analytic_area_lights() && m_scene.blocked_by_light(shadow)) {
            ws.occluded[i] = k_lamp;  // transmittance 0
            continue;
        }
        ws.rays[i] = shadow;
        ws.queries.push_back(uint32_t(i));
    }
    if (m_packet_width > 1) {
        m_scene.accel().occluded_lanes(ws.rays.data(), ws.queries.data(), ws.queries.size(), ws.occluded.data(),
                                       m_packet_width, 4, proxies);
    } else {
        for (uint32_t i : ws.queries) ws.occluded[i] = m_scene.accel().occluded(ws.rays[i], proxies) ? 1 : 0;
    }
    Spectrum L(0.f);
    for (size_t i = 0; i < n; ++i) {
        BdptConnection& k = ws.conns[i];
        Vec2 pr;
        Spectrum lp = k.result;
        if (ws.pending[i]) {
            float pass_pdf = 1.f;
            const bool occ = ws.occluded[i] != 0;
            const float tr =
                ws.occluded[i] == k_lamp
                    ? 0.f
                    : (proxies ? m_scene.transmittance_given_lights(ws.rays[i], Scene::k_no_light, occ, &pass_pdf)
                               : m_scene.transmittance_given(ws.rays[i], occ, &pass_pdf));
            lp = finish_connect(k, tr, pass_pdf, &pr);
        }
        if (is_black(lp)) continue;
        if (k.t == 1) {
            ws.splats.push_back({pr, lp});
            c.splats += 1;
        } else {
            L += lp;
        }
    }
    return L;
}

void BdptTracer::set_direct_light_tracing(const std::vector<uint32_t>& lights) {
    m_direct_light.clear();
    if (lights.empty()) return;
    m_direct_light.assign(m_scene.light_count(), 0);
    for (uint32_t i : lights)
        if (i < m_direct_light.size()) m_direct_light[i] = 1;
}

void BdptTracer::set_emission_guiding(float fraction) {
    m_guide_fraction = std::clamp(fraction, 0.f, 0.95f);
    m_guided.assign(m_scene.light_count(), 0);
    m_guided_lights = false;
    if (!(m_guide_fraction > 0.f)) return;
    m_guide = EmissionGuide(m_scene);
    if (!m_guide.active()) return;
    for (size_t i = 0; i < m_scene.light_count(); ++i) {
        if (!emission_guidable(m_scene.light(i))) continue;
        m_guided[i] = 1;
        m_guided_lights = true;
    }
}

bool BdptTracer::direct_light_tracing(const PathVertex& x0) const {
    if (m_direct_light.empty() || x0.infinite || x0.light_index < 0 ||
        size_t(x0.light_index) >= m_direct_light.size() || !m_direct_light[size_t(x0.light_index)] ||
        !m_importance.connectable())
        return false;
    const Light& l = m_scene.light(size_t(x0.light_index));
    Spectrum le;
    return !l.is_delta() && l.le_toward(x0.p, Vec3(0.f, 0.f, 1.f), &le);
}

bool BdptTracer::start_strategy(int depth, int s, int t, BdptSampler& sampler, BdptWorkspace& ws,
                                Vec2* p_raster, BdptCounters& c) const {
    if (t < 1 || s < 0 || s + t != depth + 2 || (s == 1 && t == 1)) return false;
    if (int(ws.camera.size()) < t) ws.camera.resize(size_t(t));
    if (int(ws.light.size()) < std::max(s, 1)) ws.light.resize(size_t(std::max(s, 1)));
    c.samples += 1;
    sampler.start_stream(BdptSampler::k_camera);
    const Vec2 u = sampler.next2d();
    *p_raster = Vec2(u.x * (float(m_width) + 2.f * m_margin) - m_margin,
                     u.y * (float(m_height) + 2.f * m_margin) - m_margin);
    return true;
}

Spectrum BdptTracer::evaluate_strategy(int depth, int s, int t, BdptSampler& sampler, BdptWorkspace& ws,
                                       Vec2* p_raster, BdptCounters& c, bool mis) const {
    // the scalar form of the resumable strategy below (the same steps, the queries answered
    // inline; the hot path of pssmlt)
    if (!start_strategy(depth, s, t, sampler, ws, p_raster, c)) return Spectrum(0.f);
    if (generate_camera_subpath(*p_raster, sampler, t, false, ws.camera.data(), c) != t) return Spectrum(0.f);
    sampler.start_stream(BdptSampler::k_light);
    if (s > 0 && generate_light_subpath(sampler, s, false, ws.light.data(), c, ws.camera[0].time) != s)
        return Spectrum(0.f);
    sampler.start_stream(BdptSampler::k_connection);
    return connect(ws.light.data(), s, ws.camera.data(), t, sampler, p_raster, mis, c);
}

Spectrum BdptTracer::evaluate_camera_strategies(const std::vector<float>& weights, BdptSampler& sampler,
                                                BdptWorkspace& ws, Vec2* p_raster, BdptCounters& c) const {
    if (!start_strategy(0, 0, 2, sampler, ws, p_raster, c)) return Spectrum(0.f);
    const int max_cam = m_max_depth + 2;
    if (int(ws.camera.size()) < max_cam) ws.camera.resize(size_t(max_cam));
    const int nc = generate_camera_subpath(*p_raster, sampler, max_cam, true, ws.camera.data(), c);
    if (nc < 2) return Spectrum(0.f);
    sampler.start_stream(BdptSampler::k_light);
    const int nl = generate_light_subpath(sampler, 1, false, ws.light.data(), c, ws.camera[0].time);
    sampler.start_stream(BdptSampler::k_connection);
    Spectrum L(0.f);
    for (int t = 2; t <= nc; ++t)
        for (int s = 0; s <= nl; ++s) {  // nl ≤ 1
            const int depth = s + t - 2;
            if (size_t(2 * depth + s) >= weights.size()) continue;  // beyond max_depth
            const float w = weights[size_t(2 * depth + s)];
            if (!(w > 0.f)) continue;
            Vec2 pr;
            const Spectrum C = connect(ws.light.data(), s, ws.camera.data(), t, sampler, &pr, true, c);
            if (!is_black(C)) L += C * w;
        }
    return L;
}

Spectrum BdptTracer::evaluate_strategy_unweighted(int depth, int s, int t, BdptSampler& sampler,
                                                  BdptWorkspace& ws, Vec2* p_raster,
                                                  BdptCounters& c) const {
    return evaluate_strategy(depth, s, t, sampler, ws, p_raster, c, false);
}

// ---- the resumable strategy (BdptStrategyLane), one query at a time ---------------------

BdptQuery BdptTracer::begin_strategy(BdptStrategyLane& lane, int depth, int s, int t,
                                     BdptSampler& sampler, BdptWorkspace& ws, bool mis) const {
    lane.depth = depth;
    lane.s = s;
    lane.t = t;
    lane.mis = mis;
    lane.sampler = &sampler;
    lane.ws = &ws;
    lane.result = Spectrum(0.f);
    lane.p_raster = Vec2();  // as evaluate_strategy's caller's, for a technique it rejects
    lane.counters = BdptCounters();
    lane.stage = BdptStrategyLane::Stage::done;
    if (!start_strategy(depth, s, t, sampler, ws, &lane.p_raster, lane.counters)) return BdptQuery::none;
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
    if (begin_connect(ws.light.data(), lane.s, ws.camera.data(), lane.t, *lane.sampler, lane.mis,
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

}  // namespace cmlt
