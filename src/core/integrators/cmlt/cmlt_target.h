#pragma once
/// \file Coherent MLT (DESIGN.md §3): the target f* of the chains, with coherent
/// tracing of a bundle's candidates.
///
/// A bundle's k candidates are k wrapped-Gaussian offsets of one point (mtm: x; bundle:
/// the bundle centre c, itself drawn around x) — Box–Muller Gaussians from the chain's
/// uniforms — so their camera rays are neighbours. Stratified or antithetic offsets would
/// cluster them further, but correlated candidates break the exchangeability that makes
/// bundle_step exact (the joint of x and the y_l would no longer be symmetric), so the
/// offsets are independent given the centre. The target's prepare() traces the
/// candidates together (bundle_tracer.h): with the bdpt path sampler every ray query of
/// the k lanes (camera rays, subpath bounces, shadow rays) in Embree packets
/// (rtcIntersect4/8/16, rtcOccluded4/8/16, the smallest width ≥ the lanes left, inactive
/// lanes masked off); with the pt sampler the camera rays. Or one by one when packets
/// are off. Either way each mesh hit is refined by the same double-precision
/// ray/triangle intersection (Embree's packet and single-ray kernels differ in the last
/// ulp), so packets on and off give bit-identical images.
#include "accel/accel.h"
#include "integrators/cmlt/bundle_tracer.h"
#include "integrators/cmlt/cmlt_state.h"
#include "integrators/mlt/pssmlt_tracer.h"
#include "scene/scene.h"
#include "util/cycle_clock.h"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace cmlt::coherent {

/// The target f* of the chains: evaluates points with PssmltTracer, a bundle's
/// candidates together (prepare, the kernels' batch hook), and caches the result in the
/// state (see the file comment).
struct Target {
    const mlt::PssmltTracer* tracer = nullptr;
    const Scene* scene = nullptr;
    uint64_t seed = 0;
    PathCounters* counters = nullptr;
    bool packets = true;
    int max_width = 4;  ///< Accel::max_packet_width()
    BundleCounters* bundle = nullptr;  ///< packet and bundle stats (optional)

    /// f* of one point: its cached value after prepare(), else evaluated alone (scalar
    /// queries; the same code and refined hits as a bundle's lanes).
    double operator()(const State& s) const {
        if (!s.evaluated) {
            const State* one = &s;
            evaluate(&one, 1, false);
        }
        return s.sample.f;
    }

    /// The kernels' batch hook: evaluate a bundle's n points together (see the file
    /// comment), timed for the stats.
    void prepare(State* states, size_t n) const {
        thread_local std::vector<const State*> points;
        prepare(point_list<State>(states, n, points), n);
    }
    /// The same for points anywhere (the bundles of many chains in lockstep, cmlt_chain.h).
    void prepare(const State* const* states, size_t n) const {
        BundleCounters local;
        BundleCounters& bc = bundle ? *bundle : local;
        const uint64_t t0 = cycle_now(), trace0 = Accel::trace_ticks(), rays0 = counters->rays;
        evaluate(states, n, packets);
        bc.busy_ticks += cycle_now() - t0;
        bc.trace_ticks += Accel::trace_ticks() - trace0;
        bc.bundle_rays += counters->rays - rays0;
    }

    /// Evaluate states[0..n) of one array, their rays in packets if `use_packets`.
    void evaluate(const State* states, size_t n, bool use_packets) const {
        thread_local std::vector<const State*> points;
        evaluate(point_list(states, n, points), n, use_packets);
    }
    /// Evaluate *states[0..n), their rays in packets if `use_packets`.
    void evaluate(const State* const* states, size_t n, bool use_packets) const {
        BundleCounters local;
        const RayQueries queries(scene->accel(), use_packets, max_width, bundle ? *bundle : local);
        if (tracer->bdpt()) {
            thread_local BundleEvaluator<State, PointSampler> evaluator;
            evaluator.evaluate(*tracer, *scene, seed, states, n, queries, *counters);
        } else {
            evaluate_pt(states, n, queries);
        }
        for (size_t i = 0; i < n; ++i) states[i]->evaluated = true;
    }

private:
    /// The pt path sampler: the camera rays traced together (refined first hits), the
    /// rest of each path by the path tracer alone.
    void evaluate_pt(const State* const* states, size_t n, const RayQueries& queries) const {
        thread_local std::vector<Ray> rays;
        thread_local std::vector<Hit> hits;
        if (rays.size() < n) {
            rays.resize(n);
            hits.resize(n);
        }
        for (size_t i = 0; i < n; ++i) {
            PointSampler smp(*states[i], seed);
            uint32_t pixel;
            rays[i] = tracer->camera_ray(smp, &pixel);
        }
        queries.intersect(rays.data(), n, hits.data());
        for (size_t i = 0; i < n; ++i) {
            refine_hit(*scene, rays[i], hits[i]);
            const SceneHit hit = scene->resolve_hit(rays[i], hits[i]);
            const State& s = *states[i];
            s.extent.fill(0);
            PointSampler smp(s, seed);
            s.sample = tracer->evaluate(smp, *counters, &hit);
        }
    }
};

}  // namespace cmlt::coherent
