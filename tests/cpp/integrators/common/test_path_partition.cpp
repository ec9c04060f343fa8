// The path partition (integrators/common/path_partition.h): the class of a path from its
// vertices' materials, the same for every BDPT strategy that can make the path, and the
// rule itself on hand-made paths over the glass scene (floor: rough, ball: glass).
#include "test_scenes.h"
#include "test_util.h"

#include "integrators/bdpt/bdpt_tracer.h"
#include "integrators/common/path_partition.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

using namespace cmlt;
using namespace cmlt::test;

namespace {

constexpr uint32_t k_floor = 0, k_glass = 1;

PathVertex camera_vertex() {
    PathVertex v;
    v.type = VertexType::camera;
    return v;
}
PathVertex light_vertex() {
    PathVertex v;
    v.type = VertexType::light;
    v.light_index = 0;
    return v;
}
PathVertex surface(uint32_t material) {
    PathVertex v;
    v.type = VertexType::surface;
    v.si.material_id = material;
    return v;
}

/// Every split of the path camera → mats … → light into (s, t) with s + t = its vertex
/// count (s = 0: the last vertex is an emitter hit on the camera side), classified, with
/// each scattering vertex's Dirac flag (`delta`, from the camera's side; none: all
/// false), for the strategies that can make the path: no connection at a Dirac vertex
/// (its BSDF value is 0 there; those entries are left out).
std::vector<bool> dirac_classes(const BdptTracer& tr, const std::vector<uint32_t>& mats,
                                const std::vector<bool>& delta, int32_t light_index = 0) {
    std::vector<PathVertex> full;
    full.push_back(camera_vertex());
    for (size_t i = 0; i < mats.size(); ++i) {
        full.push_back(surface(mats[i]));
        full.back().delta = delta[i];
    }
    full.push_back(light_vertex());
    full.back().light_index = light_index;
    const int n = int(full.size());
    std::vector<bool> out;
    for (int s = 0; s <= n - 1; ++s) {
        const int t = n - s;
        if (s > 0 && (full[size_t(t - 1)].delta || full[size_t(t)].delta)) continue;  // a Dirac connection
        std::vector<PathVertex> camera(full.begin(), full.begin() + t);
        std::vector<PathVertex> light;
        for (int i = n - 1; i >= t; --i) light.push_back(full[size_t(i)]);  // light[0] is the light
        out.push_back(tr.caustic_path(light.data(), s, camera.data(), t));
    }
    return out;
}
std::vector<bool> classes(const BdptTracer& tr, const std::vector<uint32_t>& mats) {
    return dirac_classes(tr, mats, std::vector<bool>(mats.size(), false));
}

}  // namespace

TEST(PathPartition, TheClassIsThePathsWhateverTheStrategy) {
    Scene s;
    glass_scene(s);
    const Camera cam(s.camera_desc(), 16, 16);
    BdptTracer tr(s, cam, 16, 16, 8);
    const PathPartition part(s, PathPart::caustic);
    EXPECT_FALSE(part.specular(k_floor));
    EXPECT_TRUE(part.specular(k_glass));
    tr.set_partition(&part);
    struct Case {
        std::vector<uint32_t> mats;  ///< scattering vertices from the camera's side
        bool caustic;
        const char* what;
    };
    const std::vector<Case> cases = {
        {{k_floor}, false, "E D L: direct light"},
        {{k_glass}, false, "E S L: the light seen through glass"},
        {{k_floor, k_floor}, false, "E D D L: indirect"},
        {{k_glass, k_floor}, false, "E S D L: a lit floor seen through glass"},
        {{k_floor, k_glass}, true, "E D S L: the caustic"},
        {{k_floor, k_glass, k_glass}, true, "E D S S L: through both faces of the ball"},
        {{k_glass, k_floor, k_glass, k_glass}, false, "E S D S S L: the caustic seen through glass (the direct pass's)"},
        {{k_glass, k_glass, k_floor, k_glass, k_glass}, false, "E S S D S S L: through both faces (the direct pass's)"},
        {{k_glass, k_floor, k_floor, k_glass}, true, "E S D D S L: two rough vertices (a caustic)"},
        {{k_floor, k_glass, k_floor, k_glass}, true, "E D S D S L: the camera sees a rough surface first"},
        {{k_glass, k_glass}, false, "E S S L: specular only"},
        {{k_floor, k_glass, k_floor}, false, "E D S D L: the last vertex rough"},
    };
    for (const Case& c : cases) {
        const std::vector<bool> got = classes(tr, c.mats);
        for (size_t s_ = 0; s_ < got.size(); ++s_)
            EXPECT_EQ(got[s_], c.caustic) << c.what << ", strategy s = " << s_;
    }
}

// RenderSettings::mlt_sds "chains": the seen-through caustics E S+ D S+ L stay with the
// chains, whatever the strategy; every other class is as with the default rule.
TEST(PathPartition, SeenThroughCausticsStayWithTheChainsWhenAsked) {
    Scene s;
    glass_scene(s);
    const Camera cam(s.camera_desc(), 16, 16);
    BdptTracer tr(s, cam, 16, 16, 8);
    const PathPartition part(s, PathPart::caustic, false);
    EXPECT_FALSE(part.seen_through_easy());
    tr.set_partition(&part);
    for (const auto& mats : std::vector<std::vector<uint32_t>>{{k_glass, k_floor, k_glass, k_glass},
                                                               {k_glass, k_glass, k_floor, k_glass, k_glass},
                                                               {k_floor, k_glass},
                                                               {k_glass, k_floor, k_floor, k_glass},
                                                               {k_floor, k_glass, k_floor, k_glass}})
        for (bool c : classes(tr, mats)) EXPECT_TRUE(c);
    for (bool c : classes(tr, {k_glass, k_floor})) EXPECT_FALSE(c);  // E S D L: not a caustic either way
    const PathPartition def(s, PathPart::caustic);
    EXPECT_TRUE(def.seen_through_easy());
    // the rule on the path tracer's summary of a path (last, rough before it, first, rough count)
    EXPECT_FALSE(def.caustic(true, true, true, 1));
    EXPECT_TRUE(part.caustic(true, true, true, 1));
    EXPECT_TRUE(def.caustic(true, true, true, 2));
    EXPECT_TRUE(def.caustic(true, true, false, 1));
    EXPECT_FALSE(def.caustic(false, true, false, 1));
}

TEST(PathPartition, WantsSplitsThePathsBetweenTheTwoParts) {
    Scene s;
    glass_scene(s);
    const PathPartition all, easy(s, PathPart::easy), caustic(s, PathPart::caustic);
    for (bool c : {false, true}) {
        EXPECT_TRUE(all.wants(c));
        EXPECT_NE(easy.wants(c), caustic.wants(c));  // exactly one of the two renders it
    }
    EXPECT_TRUE(caustic.wants(true));
    EXPECT_TRUE(easy.wants(false));
}


// RenderSettings::mlt_traced_caustics "direct" (set_traced): a caustic path whose vertex
// next to the light scattered by a Dirac lobe, whose first vertex did not, and whose
// light is traced goes to the easy part — for every strategy that can make it (the
// camera path hitting the light, s = 0, and light tracing, t = 1; the connections at a
// Dirac vertex make none); glossy chains, a Dirac first vertex and untraced lights stay
// with the chains.
TEST(PathPartition, LightTracedCausticsGoToTheDirectPass) {
    Scene s;
    glass_scene(s);
    const Camera cam(s.camera_desc(), 16, 16);
    BdptTracer tr(s, cam, 16, 16, 8);
    PathPartition part(s, PathPart::caustic);
    tr.set_partition(&part);
    auto all = [](const std::vector<bool>& v, bool want) {
        for (bool c : v)
            if (c != want) return false;
        return !v.empty();
    };
    // E D S S L through both faces of the ball, Dirac: the chains' without a traced light
    EXPECT_TRUE(all(dirac_classes(tr, {k_floor, k_glass, k_glass}, {false, true, true}), true));
    part.set_traced({1});  // light 0 traced
    EXPECT_TRUE(part.has_traced());
    const std::vector<bool> traced = dirac_classes(tr, {k_floor, k_glass, k_glass}, {false, true, true});
    EXPECT_EQ(traced.size(), 2u);  // s = 0 and t = 1
    EXPECT_TRUE(all(traced, false)) << "E D S S L with a traced light: the direct pass's";
    EXPECT_TRUE(all(dirac_classes(tr, {k_floor, k_floor, k_glass}, {false, false, true}), false))
        << "E D D S L: the direct pass's";
    // glossy last vertex (the same material, a non-Dirac lobe): the chains'
    EXPECT_TRUE(all(dirac_classes(tr, {k_floor, k_glass}, {false, false}), true)) << "E D G L";
    // Dirac first vertex: light tracing cannot connect it to the lens: the chains'
    EXPECT_TRUE(all(dirac_classes(tr, {k_glass, k_floor, k_floor, k_glass}, {true, false, false, true}), true))
        << "E S D D S L";
    // a light that is not traced (index 1: not in the table)
    EXPECT_TRUE(all(dirac_classes(tr, {k_floor, k_glass, k_glass}, {false, true, true}, 1), true));
    // not caustic stays not caustic
    EXPECT_TRUE(all(dirac_classes(tr, {k_glass, k_floor}, {true, false}), false)) << "E S D L";
    // the path tracer's summary: traced() on (first Dirac, last Dirac, light)
    EXPECT_TRUE(part.traced(false, true, 0));
    EXPECT_FALSE(part.traced(true, true, 0));
    EXPECT_FALSE(part.traced(false, false, 0));
    EXPECT_FALSE(part.traced(false, true, 1));
    EXPECT_FALSE(part.traced(false, true, -1));
    EXPECT_FALSE(part.caustic(true, true, false, 1, true));
    EXPECT_TRUE(part.caustic(true, true, false, 1, false));
}
