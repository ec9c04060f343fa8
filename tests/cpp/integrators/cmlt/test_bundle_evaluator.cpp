// Coherent MLT's lockstep bundle evaluation (integrators/cmlt/bundle_tracer.h), driven
// directly: a bundle traced with Embree packets gives, lane by lane, bit for bit the
// path sample of the same point evaluated alone with scalar queries, on a scene whose
// paths cross pass-through surfaces, hit a sphere light and end on emitters (every kind
// of query the lanes make). The same for the pt path sampler's camera-ray packets. And
// the lanes agree with the plain (unrefined) scalar path sampler up to the refinement
// of hit distances.
#include "test_scenes.h"
#include "test_util.h"

#include "accel/accel.h"
#include "integrators/cmlt/bundle_tracer.h"
#include "integrators/cmlt/cmlt_target.h"
#include "integrators/cmlt/perturbations.h"
#include "integrators/mlt/mlt_context.h"
#include "integrators/path/path_tracer_impl.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

using namespace cmlt;
using namespace cmlt::coherent;
using namespace cmlt::test;

namespace {

constexpr uint64_t k_seed = 21;

RenderSettings bundle_settings(const char* path_sampler) {
    RenderSettings s;
    s.width = 32;
    s.height = 32;
    s.max_depth = 6;
    s.seed = k_seed;
    s.integrator = "cmlt";
    s.importance = "luminance";
    s.direct_fraction = 0.0;
    s.mlt_path_sampler = path_sampler;
    return s;
}

/// 24 independent points and 8 lens-perturbed neighbours of the first of them whose
/// technique connects a light subpath to a camera subpath (s ≥ 1, t ≥ 2: a bundle whose
/// lanes all end in a shadow ray, in the same round), as the inner chain draws a bundle.
std::vector<State> test_states(const mlt::PssmltTracer& tracer, int width, int height) {
    std::vector<State> out;
    size_t centre = 0;
    bool found = false;
    for (uint32_t i = 0; i < 24; ++i) {
        State s;
        s.key = StateKey{RngDomain::test, i, 1};
        out.push_back(s);
        if (found || !tracer.bdpt()) continue;
        // the technique, as the lanes read it: connection stream, dimension 0
        const float u0 = unit_float(key_value(k_seed, s.key, MltSampler::index(MltSampler::connection, 0)));
        const float u1 = unit_float(key_value(k_seed, s.key, MltSampler::index(MltSampler::connection, 1)));
        int depth, st, tt;
        tracer.technique().choose(u0, u1, &depth, &st, &tt);
        if (st >= 1 && tt >= 2) {
            centre = i;
            found = true;
        }
    }
    EXPECT_TRUE(found || !tracer.bdpt());
    CounterRng rng(k_seed, RngDomain::test, 1000);
    const PerturbationProposal lens =
        PerturbationProposal::make(Perturbation::lens, k_seed, 2.0, 0.01, width, height, rng);
    for (int k = 0; k < 8; ++k) {
        State y;
        lens.sample(out[centre], y, rng);
        out.push_back(y);
    }
    return out;
}

bool same_bits(float a, float b) { return std::memcmp(&a, &b, sizeof(float)) == 0; }

void expect_same_sample(const State& a, const State& b, size_t lane) {
    EXPECT_EQ(a.sample.pixel, b.sample.pixel) << "lane " << lane;
    EXPECT_TRUE(same_bits(a.sample.L.x, b.sample.L.x) && same_bits(a.sample.L.y, b.sample.L.y) &&
                same_bits(a.sample.L.z, b.sample.L.z))
        << "lane " << lane << ": L " << a.sample.L.x << " vs " << b.sample.L.x;
    EXPECT_EQ(a.sample.f, b.sample.f) << "lane " << lane;
    EXPECT_EQ(a.sample.invalid, b.sample.invalid) << "lane " << lane;
    EXPECT_EQ(a.sample.depth, b.sample.depth) << "lane " << lane;
    EXPECT_EQ(a.sample.s, b.sample.s) << "lane " << lane;
    EXPECT_EQ(a.sample.t, b.sample.t) << "lane " << lane;
    EXPECT_EQ(a.extent, b.extent) << "lane " << lane;
}

}  // namespace

TEST(BundleEvaluator, PacketLanesEqualScalarEvaluationsBitForBit) {
    Scene scene;
    pass_through_box(scene);
    const RenderSettings settings = bundle_settings("bdpt");
    PathCounters pilot;
    const mlt::MltContext ctx(scene, settings, pilot);
    const int width = Accel::max_packet_width();
    ASSERT_GE(width, 4) << "this CPU has no native packets: the test needs them";

    std::vector<State> packed = test_states(ctx.tracer, settings.width, settings.height);
    std::vector<State> alone = packed;
    BundleCounters bundle;
    PathCounters packed_rays, alone_rays;
    BundleEvaluator<State, PointSampler> evaluator;
    evaluator.evaluate(ctx.tracer, scene, k_seed, packed.data(), packed.size(),
                       RayQueries(scene.accel(), true, width, bundle), packed_rays);
    BundleCounters scalar;
    for (State& s : alone)
        evaluator.evaluate(ctx.tracer, scene, k_seed, &s, 1, RayQueries(scene.accel(), false, width, scalar),
                           alone_rays);
    EXPECT_EQ(scalar.packets, 0u);
    EXPECT_GT(bundle.packets, 0u);
    EXPECT_GT(bundle.packet_shadow_rays, 0u);          // connections went through packets too
    EXPECT_GT(bundle.packet_rays, bundle.packet_shadow_rays);  // and walks / camera rays
    int lit = 0, light_traced = 0;
    for (size_t i = 0; i < packed.size(); ++i) {
        expect_same_sample(packed[i], alone[i], i);
        lit += packed[i].sample.f > 0.0 ? 1 : 0;
        light_traced += packed[i].sample.t == 1 ? 1 : 0;
    }
    EXPECT_EQ(packed_rays.rays, alone_rays.rays);
    EXPECT_EQ(packed_rays.shadow_rays, alone_rays.shadow_rays);
    EXPECT_GE(lit, 8) << "too few lanes carry light to compare";
    EXPECT_GE(light_traced, 1);
}

TEST(BundleEvaluator, LanesAgreeWithThePlainScalarPathSampler) {
    // The plain path sampler (PssmltTracer::evaluate over PointSampler) traces with
    // Embree's own hit distances; the lanes refine every hit in double precision. The
    // paths are the same (technique, pixel) and their values agree to float accuracy.
    Scene scene;
    pass_through_box(scene);
    const RenderSettings settings = bundle_settings("bdpt");
    PathCounters pilot, c;
    const mlt::MltContext ctx(scene, settings, pilot);
    std::vector<State> lanes = test_states(ctx.tracer, settings.width, settings.height);
    BundleCounters bundle;
    BundleEvaluator<State, PointSampler> evaluator;
    evaluator.evaluate(ctx.tracer, scene, k_seed, lanes.data(), lanes.size(),
                       RayQueries(scene.accel(), true, Accel::max_packet_width(), bundle), c);
    int compared = 0, close = 0;
    for (size_t i = 0; i < lanes.size(); ++i) {
        State s = lanes[i];
        PointSampler smp(s, k_seed);
        const mlt::PathSample plain = ctx.tracer.evaluate(smp, c);
        EXPECT_EQ(plain.depth, lanes[i].sample.depth) << i;
        EXPECT_EQ(plain.s, lanes[i].sample.s) << i;
        EXPECT_EQ(plain.t, lanes[i].sample.t) << i;
        if (lanes[i].sample.t >= 2) {
            EXPECT_EQ(plain.pixel, lanes[i].sample.pixel) << i;  // the film position, before any ray
        }
        if (plain.f > 0.0 || lanes[i].sample.f > 0.0) {
            ++compared;
            close += std::fabs(plain.f - lanes[i].sample.f) <= 1e-4 * std::max(plain.f, lanes[i].sample.f) ? 1 : 0;
        }
    }
    ASSERT_GE(compared, 8);
    // a grazing hit may take another branch after a one-ulp difference; nearly all agree
    EXPECT_GE(close, compared - 1) << close << " of " << compared;
}

TEST(BundleEvaluator, PtSamplerCameraRayPacketsEqualScalarRays) {
    Scene scene;
    glass_scene(scene);
    const RenderSettings settings = bundle_settings("pt");
    PathCounters pilot, c;
    const mlt::MltContext ctx(scene, settings, pilot);
    Target f;
    f.tracer = &ctx.tracer;
    f.scene = &scene;
    f.seed = k_seed;
    f.counters = &c;
    f.max_width = Accel::max_packet_width();
    BundleCounters bundle;
    f.bundle = &bundle;
    std::vector<State> packed = test_states(ctx.tracer, settings.width, settings.height);
    std::vector<State> alone = packed;
    f.evaluate(packed.data(), packed.size(), true);
    EXPECT_GT(bundle.packets, 0u);
    int lit = 0;
    for (size_t i = 0; i < packed.size(); ++i) {
        EXPECT_EQ(f(alone[i]), packed[i].sample.f) << i;  // alone: scalar, one at a time
        expect_same_sample(packed[i], alone[i], i);
        EXPECT_EQ(packed[i].sample.t, -1) << "the pt sampler has no technique";
        lit += packed[i].sample.f > 0.0 ? 1 : 0;
    }
    EXPECT_GE(lit, 8);
}
