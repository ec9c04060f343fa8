#pragma once
/// \file Lockstep evaluation of a bundle's candidates with packet ray queries (DESIGN.md
/// §3 "Coherence"; what is and is not traced in packets: cmlt_target.h). Packets pay
/// little here: the BVH queries are ~15–20 % of a bundle's time (shading dominates), so
/// the whole frame gains 0.96–1.12×, not the 1.5–2.5× Segovia et al. report for SSE
/// packets (README, benchmarks).
///
/// Every candidate of a bundle is one lane: a resumable BDPT strategy evaluation
/// (BdptLane over BdptStrategyLane) that stops at each ray query. A round
/// collects the pending queries of all lanes — closest hits (camera rays, the walks'
/// bounces and pass-through crossings) and visibility (connection, next-event and
/// light-tracing shadow rays) — and answers them together: Embree packets of the
/// smallest native width that holds the lanes left (rtcIntersect4/8/16,
/// rtcOccluded4/8/16, inactive lanes masked off), or one query at a time when packets
/// are off. Lanes never interact, so the rounds only decide how queries are grouped,
/// never what a lane computes: with the same answers a lane's result is
/// BdptTracer::evaluate_strategy's.
///
/// Same answers in both modes. Embree's packet and single-ray kernels may differ in the
/// last ulp of a hit's t, u, v, so every closest hit (packet or not) is refined by one
/// double-precision ray/triangle intersection (refine_hit) that depends only on the ray
/// and the triangle. Occlusion is a yes/no answer; a visibility query reproduces
/// Scene::transmittance: analytic lights first (blocked_by_light, not in the BVH), then
/// the occlusion query, and only for a lane that something occludes in a scene with
/// pass-through surfaces the scalar stepping through them (Scene::transmittance_given,
/// whose hits are the same scalar queries in both modes).
#include "accel/accel.h"
#include "integrators/bdpt/bdpt_tracer.h"
#include "integrators/mlt/pssmlt_tracer.h"
#include "scene/scene.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

namespace cmlt::coherent {

/// Counters of the bundles' tracing, for the render stats (integer sums).
struct BundleCounters {
    uint64_t packets = 0;             ///< packet queries (rtcIntersectN + rtcOccludedN calls)
    uint64_t packet_rays = 0;         ///< rays answered by a packet (its active lanes)
    uint64_t packet_shadow_rays = 0;  ///< of them, visibility rays (rtcOccludedN)
    uint64_t bundle_rays = 0;         ///< rays of the bundles' evaluations (PathCounters::rays)
    uint64_t busy_ticks = 0;          ///< ticks spent evaluating bundles
    uint64_t trace_ticks = 0;         ///< of them, inside BVH queries (Accel::trace_ticks)

    void merge(const BundleCounters& o) {
        packets += o.packets;
        packet_rays += o.packet_rays;
        packet_shadow_rays += o.packet_shadow_rays;
        bundle_rays += o.bundle_rays;
        busy_ticks += o.busy_ticks;
        trace_ticks += o.trace_ticks;
    }
};

/// Fewer pending queries than this are answered one ray at a time: a packet query costs
/// about as much with few active lanes as with all, and more than a few scalar queries.
/// Measurements: tests/bench/results/packets.md.
inline constexpr size_t k_min_packet_lanes = 4;

/// Refine a mesh hit of `ray` by a double-precision Möller–Trumbore intersection with
/// the hit triangle (as placed by Scene::fill_interaction): Embree's packet and
/// single-ray kernels may differ in the last ulp of t, u, v; the refined values depend
/// only on (ray, instance, triangle). A degenerate or grazing case keeps Embree's values.
inline void refine_hit(const Scene& scene, const Ray& ray, Hit& h) {
    if (!h.valid()) return;
    const Instance& inst = scene.instance(h.instance_id);
    const Mesh& mesh = scene.mesh(inst.mesh_id);
    uint32_t v[3];
    mesh.triangle(h.prim_id, v);
    const Mat4 m = inst.motion.size() > 1 ? inst.matrix_at(ray.time) : inst.xf.m;
    const Vec3 p0 = m.transform_point(mesh.point(v[0]));
    const Vec3 p1 = m.transform_point(mesh.point(v[1]));
    const Vec3 p2 = m.transform_point(mesh.point(v[2]));
    const double e1[3] = {double(p1.x) - p0.x, double(p1.y) - p0.y, double(p1.z) - p0.z};
    const double e2[3] = {double(p2.x) - p0.x, double(p2.y) - p0.y, double(p2.z) - p0.z};
    const double d[3] = {ray.d.x, ray.d.y, ray.d.z};
    const double o[3] = {double(ray.o.x) - p0.x, double(ray.o.y) - p0.y, double(ray.o.z) - p0.z};
    auto cross3 = [](const double* a, const double* b, double* c) {
        c[0] = a[1] * b[2] - a[2] * b[1];
        c[1] = a[2] * b[0] - a[0] * b[2];
        c[2] = a[0] * b[1] - a[1] * b[0];
    };
    auto dot3 = [](const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; };
    double pv[3], qv[3];
    cross3(d, e2, pv);
    const double det = dot3(e1, pv);
    if (!(std::fabs(det) > 1e-300) || !std::isfinite(det)) return;
    const double inv = 1.0 / det;
    cross3(o, e1, qv);
    const double u = dot3(o, pv) * inv, w = dot3(d, qv) * inv, t = dot3(e2, qv) * inv;
    if (!std::isfinite(u) || !std::isfinite(w) || !std::isfinite(t)) return;
    h.t = float(t);
    h.u = float(std::min(std::max(u, 0.0), 1.0));
    h.v = float(std::min(std::max(w, 0.0), 1.0));
}

/// One round's ray queries, answered in packets or one by one (see the file comment).
class RayQueries {
public:
    RayQueries(const Accel& accel, bool packets, int max_width, BundleCounters& counters)
        : m_accel(accel), m_packets(packets && max_width >= 4), m_max_width(max_width),
          m_counters(counters) {}

    /// Closest hits of rays[0..n) (unrefined).
    void intersect(const Ray* rays, size_t n, Hit* hits) const {
        answer(
            rays, n, hits, [&](const Ray& r) { return m_accel.intersect(r); },
            [&](int width, const int* valid, const Ray* lanes, Hit* out) {
                m_accel.intersect_packet(width, valid, lanes, out);
            });
    }
    /// Whether something in the BVH blocks each of rays[0..n).
    void occluded(const Ray* rays, size_t n, bool* occluded) const {
        const uint64_t before = m_counters.packet_rays;
        answer(
            rays, n, occluded, [&](const Ray& r) { return m_accel.occluded(r); },
            [&](int width, const int* valid, const Ray* lanes, bool* out) {
                m_accel.occluded_packet(width, valid, lanes, out);
            });
        m_counters.packet_shadow_rays += m_counters.packet_rays - before;
    }

private:
    /// Split n lanes into packets of the smallest native width holding the lanes left
    /// (at most max_width); `one(p)` answers lane p alone, `packet(width, valid, p,
    /// lanes)` lanes p .. p + lanes.
    template <class One, class Packet>
    void for_packets(size_t n, One&& one, Packet&& packet) const {
        if (!m_packets) {
            for (size_t p = 0; p < n; ++p) one(p);
            return;
        }
        alignas(64) int valid[16];
        for (size_t p = 0; p < n;) {
            const size_t left = n - p;
            const int width = std::min(left <= 4 ? 4 : (left <= 8 ? 8 : 16), m_max_width);
            const size_t lanes = std::min(left, size_t(width));
            if (lanes < k_min_packet_lanes) {
                one(p);
                ++p;
                continue;
            }
            for (int i = 0; i < width; ++i) valid[i] = size_t(i) < lanes ? -1 : 0;
            packet(width, valid, p, lanes);
            ++m_counters.packets;
            m_counters.packet_rays += lanes;
            p += lanes;
        }
    }
    /// out[0..n) for rays[0..n): `one(ray)` alone, or `packet(width, valid, lane rays,
    /// lane answers)` for a packet (for_packets decides).
    template <class Answer, class One, class Packet>
    void answer(const Ray* rays, size_t n, Answer* out, One&& one, Packet&& packet) const {
        for_packets(n, [&](size_t p) { out[p] = one(rays[p]); },
                    [&](int width, const int* valid, size_t p, size_t lanes) {
                        Ray lane_rays[16];
                        Answer lane_out[16];
                        fill_lanes(rays, p, lanes, width, lane_rays);
                        packet(width, valid, lane_rays, lane_out);
                        for (size_t i = 0; i < lanes; ++i) out[p + i] = lane_out[i];
                    });
    }
    /// Embree reads every lane of a packet: inactive ones repeat the first ray.
    static void fill_lanes(const Ray* rays, size_t p, size_t lanes, int width, Ray* out) {
        for (int i = 0; i < width; ++i) out[i] = rays[p + (size_t(i) < lanes ? size_t(i) : 0)];
    }

    const Accel& m_accel;
    bool m_packets;
    int m_max_width;
    BundleCounters& m_counters;
};

/// One candidate of a bundle with the bdpt path sampler: PssmltTracer::evaluate as a
/// resumable computation (BdptStrategyLane), so that a bundle's candidates run in
/// lockstep and their rays are traced together.
struct BdptLane {
    mlt::PathSample sample;  ///< technique until finish_lane, then the evaluated sample
    double pmf = 1.0;        ///< probability of the technique
    BdptStrategyLane strategy;
};

/// Read the technique from `sampler` and begin its strategy with `adapter` (a
/// BdptStreamAdapter over `sampler`, outliving the lane). Returns the first query;
/// answer each with BdptTracer::resume_strategy until none, then finish_lane.
template <class Sampler>
BdptQuery begin_lane(const mlt::PssmltTracer& tracer, Sampler& sampler, BdptSampler& adapter, BdptWorkspace& ws,
                     BdptLane& lane) {
    lane.sample = mlt::PathSample();
    lane.pmf = tracer.choose_technique(sampler, lane.sample);
    if (lane.sample.depth < 0) {
        // the camera technique (mlt/technique.h): evaluated here, its queries answered
        // inline in both modes (so packets stay bit-identical to --no-packets)
        BdptStrategyLane& st = lane.strategy;
        st.counters = BdptCounters();
        st.p_raster = Vec2();
        st.result = tracer.evaluate_technique(lane.sample, adapter, ws, &st.p_raster, st.counters);
        return BdptQuery::none;
    }
    return tracer.bdpt_tracer()->begin_strategy(lane.strategy, lane.sample.depth, lane.sample.s, lane.sample.t,
                                                adapter, ws);
}

/// The path sample of a finished lane (its rays added to `counters`).
inline mlt::PathSample finish_lane(const mlt::PssmltTracer& tracer, const BdptLane& lane, PathCounters& counters) {
    mlt::PathSample s = lane.sample;
    tracer.finish_sample(s, lane.pmf, lane.strategy.result, lane.strategy.p_raster, lane.strategy.counters,
                         counters);
    return s;
}

/// The addresses of states[0..n) in `out` (resized): the point lists of BundleEvaluator
/// and Target for the points of one array.
template <class State>
const State* const* point_list(const State* states, size_t n, std::vector<const State*>& out) {
    out.resize(n);
    for (size_t i = 0; i < n; ++i) out[i] = &states[i];
    return out.data();
}

/// Evaluates points with the bdpt path sampler in lockstep (see the file comment).
/// `State`: a point with mutable `extent` (reset here) and `sample` (the result);
/// `Sampler`: the point's sampler, constructible from (const State&, seed). Scratch is
/// kept between calls (one evaluator per thread).
template <class State, class Sampler>
class BundleEvaluator {
public:
    /// states[0..n): the points (pointers: a round of coherent MLT's chains in lockstep
    /// evaluates the bundles of many chains' workspaces together).
    void evaluate(const mlt::PssmltTracer& tracer, const Scene& scene, uint64_t seed, const State* const* states,
                  size_t n, const RayQueries& queries, PathCounters& counters) {
        reserve(n);
        const BdptTracer& bdpt = *tracer.bdpt_tracer();
        // begin every lane: technique, film position, camera vertex, up to its first query
        for (size_t i = 0; i < n; ++i) {
            states[i]->extent.fill(0);
            m_samplers[i].emplace(*states[i], seed);
            m_adapters[i].emplace(*m_samplers[i], tracer.film_map());
            m_query[i] = begin_lane(tracer, *m_samplers[i], *m_adapters[i], m_ws[i], m_lanes[i]);
        }
        // rounds: every lane's pending query answered together, until none is left
        for (;;) {
            size_t count = 0;
            for (size_t i = 0; i < n; ++i) {
                if (m_query[i] != BdptQuery::intersect) continue;
                m_index[count] = uint32_t(i);
                m_rays[count++] = m_lanes[i].strategy.walk.ray;
            }
            if (count > 0) {
                queries.intersect(m_rays.data(), count, m_hits.data());
                for (size_t j = 0; j < count; ++j) {
                    refine_hit(scene, m_rays[j], m_hits[j]);
                    const uint32_t i = m_index[j];
                    m_query[i] = bdpt.resume_strategy(m_lanes[i].strategy, scene.resolve_hit(m_rays[j], m_hits[j]));
                }
            }
            size_t waiting = 0;
            count = 0;
            for (size_t i = 0; i < n; ++i) {
                if (m_query[i] != BdptQuery::visibility) continue;
                const Ray& ray = m_lanes[i].strategy.conn.shadow;
                // Scene::transmittance's order: analytic lights are not in the BVH
                if (scene.blocked_by_light(ray)) {
                    m_query[i] = bdpt.resume_strategy(m_lanes[i].strategy, 0.f, 1.f);
                    continue;
                }
                m_index[count] = uint32_t(i);
                m_rays[count++] = ray;
            }
            if (count > 0) {
                queries.occluded(m_rays.data(), count, m_occluded.get());
                for (size_t j = 0; j < count; ++j) {
                    float pass_pdf = 1.f;
                    const float tr = scene.transmittance_given(m_rays[j], m_occluded[j], &pass_pdf);
                    const uint32_t i = m_index[j];
                    m_query[i] = bdpt.resume_strategy(m_lanes[i].strategy, tr, pass_pdf);
                }
            }
            for (size_t i = 0; i < n; ++i) waiting += m_query[i] != BdptQuery::none ? 1 : 0;
            if (waiting == 0) break;
        }
        for (size_t i = 0; i < n; ++i) states[i]->sample = finish_lane(tracer, m_lanes[i], counters);
    }

    /// The points states[0..n) of one array.
    void evaluate(const mlt::PssmltTracer& tracer, const Scene& scene, uint64_t seed, const State* states,
                  size_t n, const RayQueries& queries, PathCounters& counters) {
        evaluate(tracer, scene, seed, point_list(states, n, m_points), n, queries, counters);
    }

private:
    void reserve(size_t n) {
        if (m_lanes.size() >= n) return;
        m_lanes.resize(n);
        m_ws.resize(n);
        m_samplers.resize(n);
        m_adapters.resize(n);
        m_query.resize(n);
        m_index.resize(n);
        m_rays.resize(n);
        m_hits.resize(n);
        m_occluded.reset(new bool[n]);
    }

    std::vector<BdptLane> m_lanes;
    std::vector<BdptWorkspace> m_ws;
    std::vector<std::optional<Sampler>> m_samplers;
    std::vector<std::optional<mlt::BdptStreamAdapter<Sampler>>> m_adapters;
    std::vector<BdptQuery> m_query;
    std::vector<uint32_t> m_index;
    std::vector<Ray> m_rays;
    std::vector<Hit> m_hits;
    std::unique_ptr<bool[]> m_occluded;
    std::vector<const State*> m_points;
};

}  // namespace cmlt::coherent
