// render() and its table of integrators (integrators/common/render.cpp): every name the
// settings accept has a frame loop, and nothing else does.
#include "test_util.h"

#include "integrators/common/render.h"
#include "util/error.h"

#include <gtest/gtest.h>

#include <set>
#include <string>

using namespace cmlt;
using namespace cmlt::test;

TEST(Render, TheTableHoldsEveryIntegratorTheSettingsAccept) {
    size_t n = 0;
    const IntegratorEntry* table = integrator_table(&n);
    std::set<std::string> names;
    for (size_t i = 0; i < n; ++i) {
        ASSERT_NE(table[i].render, nullptr) << table[i].name;
        EXPECT_TRUE(names.insert(table[i].name).second) << "twice: " << table[i].name;
        RenderSettings s;
        s.integrator = table[i].name;
        EXPECT_NO_THROW(s.validate()) << table[i].name;
    }
    EXPECT_EQ(names, (std::set<std::string>{"pt", "bdpt", "pssmlt", "cmlt"}));
    RenderSettings bad;
    bad.integrator = "mlt";
    try {
        bad.validate();
        FAIL() << "validate accepted integrator 'mlt'";
    } catch (const SettingsError& e) {
        EXPECT_NE(std::string(e.what()).find("integrator"), std::string::npos) << e.what();
    }
}

TEST(Render, EveryIntegratorRendersAFrameOfItsSize) {
    Scene scene;
    scene.set_materials({Material{Spectrum(0.5f), Spectrum(0.f)}, Material{Spectrum(0.f), Spectrum(4.f)}});
    scene.add_instance(scene.add_mesh("/floor", quad_mesh(Vec3(0.f), Vec3(2, 0, 0), Vec3(0, 0, -2))), Mat4());
    scene.add_instance(scene.add_mesh("/lamp", quad_mesh(Vec3(0, 1.5f, 0), Vec3(0.3f, 0, 0), Vec3(0, 0, 0.3f), 1)),
                       Mat4());
    scene.set_camera(camera_at(Mat4::translate(0, 1, 3), 35.f, 36.f));
    size_t n = 0;
    const IntegratorEntry* table = integrator_table(&n);
    for (size_t i = 0; i < n; ++i) {
        RenderSettings s;
        s.width = 12;
        s.height = 9;
        s.spp = 8;
        s.threads = 2;
        s.chains = 8;
        s.bootstrap_samples = 64;
        s.integrator = table[i].name;
        const RenderResult r = render(scene, s);
        EXPECT_EQ(r.width, 12) << table[i].name;
        EXPECT_EQ(r.height, 9) << table[i].name;
        EXPECT_EQ(r.image.size(), size_t(12 * 9 * 3)) << table[i].name;
        EXPECT_EQ(r.stats.integrator, table[i].name);
        double sum = 0.0;
        for (float v : r.image) sum += v;
        EXPECT_GT(sum, 0.0) << table[i].name;
    }
}
