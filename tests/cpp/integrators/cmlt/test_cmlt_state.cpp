// Coherent MLT's chain state (integrators/cmlt/cmlt_state.h): a key plus overrides. The
// key's values are MltSampler's large-step values bit for bit (so bootstrap sample i is
// PSSMLT's), an override beats the key, the point sampler reads the MltSampler layout and
// records the extent, and export / import round-trip a state exactly.
#include "integrators/cmlt/cmlt_state.h"
#include "integrators/cmlt/perturbations.h"
#include "integrators/mlt/mlt_sampler.h"
#include "sampling/rng.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace cmlt;
using namespace cmlt::coherent;

namespace {

constexpr uint64_t k_seed = 12345;

// The samplers the path routines read (base/sampler.h).
struct NoStreams {
    void set_dimension(uint32_t) {}
    float get1d() { return 0.f; }
    Vec2 get2d() { return {}; }
};
static_assert(is_stream_sampler_v<PointSampler> && is_stream_sampler_v<MltSampler>);
static_assert(is_path_sampler_v<PixelSampler> && !is_stream_sampler_v<PixelSampler>);
static_assert(is_path_sampler_v<NoStreams> && !is_stream_sampler_v<NoStreams>);
static_assert(!is_path_sampler_v<State>);

}  // namespace

TEST(CmltState, KeyValuesAreTheLargeStepOfMltSamplerBitForBit) {
    for (uint32_t id : {0u, 7u, 4095u}) {
        MltSampler smp(k_seed, 0.01, 1.0, RngDomain::bootstrap, id);
        smp.start_iteration(true);  // proposal 1: the bootstrap sample
        const StateKey key{RngDomain::bootstrap, id, 1};
        for (size_t i = 0; i < 40; ++i) EXPECT_EQ(smp.sample(i), key_value(k_seed, key, i)) << "id " << id << " i " << i;
    }
    // a later proposal of a chain: the key's proposal number
    MltSampler smp(k_seed, 0.01, 1.0, RngDomain::chain, 3);
    for (int p = 0; p < 5; ++p) {
        smp.start_iteration(true);
        smp.accept();
    }
    const StateKey key{RngDomain::chain, 3, 5};
    for (size_t i = 0; i < 12; ++i) EXPECT_EQ(smp.sample(i), key_value(k_seed, key, i)) << i;
}

TEST(CmltState, OverridesBeatTheKeyAndUnsetOnesFallBackToIt) {
    State s;
    s.key = StateKey{RngDomain::chain, 2, 9};
    EXPECT_EQ(s.value(k_seed, 5), key_value(k_seed, s.key, 5));
    s.set(5, 0.25);
    EXPECT_EQ(s.u.size(), 6u);
    EXPECT_EQ(s.value(k_seed, 5), 0.25);
    for (size_t i = 0; i < 5; ++i) {
        EXPECT_TRUE(std::isnan(s.u[i])) << i;  // grown with "no value"
        EXPECT_EQ(s.value(k_seed, i), key_value(k_seed, s.key, i)) << i;
    }
    EXPECT_EQ(s.value(k_seed, 100), key_value(k_seed, s.key, 100));
    // a large step: the new key, no overrides, evaluated again
    s.evaluated = true;
    State to;
    CounterRng rng(1, RngDomain::test, 0);
    LargeStepProposal{StateKey{RngDomain::chain, 2, 10}}.sample(s, to, rng);
    EXPECT_TRUE(to.u.empty());
    EXPECT_EQ(to.key.proposal, 10u);
    EXPECT_FALSE(to.evaluated);
}

TEST(CmltState, PointSamplerReadsTheMltSamplerLayoutAndRecordsTheExtent) {
    State s;
    s.key = StateKey{RngDomain::chain, 1, 4};
    s.set(MltSampler::index(MltSampler::light, 3), 0.75);  // light stream, dimension 1, second slot
    PointSampler ps(s, k_seed);
    ps.start_stream(MltSampler::camera);
    const Vec2 film = ps.get2d();
    EXPECT_EQ(film.x, unit_float(s.value(k_seed, MltSampler::index(MltSampler::camera, 0))));
    EXPECT_EQ(film.y, unit_float(s.value(k_seed, MltSampler::index(MltSampler::camera, 1))));
    EXPECT_EQ(ps.get1d(), unit_float(s.value(k_seed, MltSampler::index(MltSampler::camera, 2))));
    ps.start_stream(MltSampler::light);
    EXPECT_EQ(ps.dimension(), 0u);
    ps.set_dimension(1);
    const Vec2 l = ps.get2d();
    EXPECT_EQ(l.y, 0.75f);
    EXPECT_EQ(s.extent[MltSampler::camera], 3u);  // slots 0, 1 (get2d) and 2 (get1d)
    EXPECT_EQ(s.extent[MltSampler::light], 4u);   // up to slot 3
    EXPECT_EQ(s.extent[MltSampler::connection], 0u);
}

TEST(CmltState, ExportAndImportRoundTripTheReadCoordinates) {
    State x;
    x.key = StateKey{RngDomain::bootstrap, 17, 1};
    x.set(MltSampler::index(MltSampler::camera, 1), 0.5);
    x.extent = {4, 6, 2};
    x.sample.depth = 3;
    x.sample.s = 2;
    x.sample.t = 3;
    x.sample.f = 0.125;
    const mlt::ChainState out = export_state(x, k_seed, 42);
    EXPECT_EQ(out.chain_id, 42u);
    EXPECT_EQ(out.depth, 3u);
    EXPECT_EQ(out.t, 3u);
    EXPECT_EQ(out.f_star, 0.125);
    for (uint32_t k = 0; k < MltSampler::k_stream_count; ++k) {
        ASSERT_EQ(out.u[k].size(), x.extent[k]);
        for (uint32_t slot = 0; slot < x.extent[k]; ++slot)
            EXPECT_EQ(out.u[k][slot], unit_float(x.value(k_seed, MltSampler::index(k, slot))));
    }
    // imported under another key: the exported coordinates are kept (as the floats a
    // path reads), the rest come from the new key
    const StateKey fresh{RngDomain::chain, 17, 0};
    const State y = import_state(out, fresh);
    for (uint32_t k = 0; k < MltSampler::k_stream_count; ++k)
        for (uint32_t slot = 0; slot < 10; ++slot) {
            const size_t i = MltSampler::index(k, slot);
            if (slot < x.extent[k]) EXPECT_EQ(y.value(k_seed, i), double(out.u[k][slot]));
            else EXPECT_EQ(y.value(k_seed, i), key_value(k_seed, fresh, i));
        }
    // exporting the imported state again gives the same state (the carried point is
    // the same point bit for bit)
    State z = y;
    z.extent = x.extent;
    z.sample = x.sample;
    const mlt::ChainState again = export_state(z, k_seed, 42);
    for (uint32_t k = 0; k < MltSampler::k_stream_count; ++k) EXPECT_EQ(again.u[k], out.u[k]);
    // a NaN slot (no value) falls back to the key
    mlt::ChainState holes = out;
    holes.u[MltSampler::light][2] = std::nanf("");
    const State w = import_state(holes, fresh);
    const size_t hole = MltSampler::index(MltSampler::light, 2);
    EXPECT_EQ(w.value(k_seed, hole), key_value(k_seed, fresh, hole));
}
