// EmissionGuide::coverage and caster_coverage (lights/emission_guide.h): the share of the
// directions from a light that the casters' cones cover, which decides the Metropolis
// integrators' auto guiding (integrators/mlt/mlt_context.h).
#include "lights/emission_guide.h"
#include "scene/scene.h"
#include "test_scenes.h"

#include <gtest/gtest.h>

#include <cmath>

using namespace cmlt;
using namespace cmlt::test;

namespace {

/// The glass ball of glass_scene_unlit (radius 0.4 at (0, 0.41, 0), a 48 x 24 UV sphere:
/// its bounding box is the cube of half-width 0.4, the guide's sphere 0.4·√3 (+0.1 %))
/// under sphere lights at `centers` with radiance `radiance` each.
void ball_under_lights(Scene& s, const std::vector<Vec3>& centers, const std::vector<float>& radiance) {
    glass_scene_unlit(s);
    for (size_t i = 0; i < centers.size(); ++i) s.add_light(sphere_light(centers[i], 0.02f, Spectrum(radiance[i])));
    s.commit();
}

double cone_share(double r, double d) { return 0.5 * (1.0 - std::sqrt(1.0 - r * r / (d * d))); }

}  // namespace

TEST(EmissionGuide, CoverageIsTheCastersConeShare) {
    Scene s;
    ball_under_lights(s, {Vec3(0.f, 3.f, 0.f)}, {10.f});
    const EmissionGuide guide(s);
    ASSERT_TRUE(guide.active());
    ASSERT_EQ(guide.caster_count(), 1u);  // the ball; the floor is diffuse
    const double r = 0.4 * std::sqrt(3.0) * 1.001;
    const Vec3 c(0.f, 0.41f, 0.f);
    for (float d : {1.f, 2.f, 5.f, 20.f}) {
        const Vec3 y = c + Vec3(0.f, d, 0.f);
        EXPECT_NEAR(guide.coverage(y), cone_share(r, d), 1e-3 * cone_share(r, d)) << "distance " << d;
    }
    EXPECT_GT(guide.coverage(c + Vec3(0.f, 1.f, 0.f)), guide.coverage(c + Vec3(0.f, 2.f, 0.f)));
    EXPECT_EQ(guide.coverage(c), 1.0);                         // inside the sphere
    EXPECT_EQ(guide.coverage(c + Vec3(0.5f, 0.f, 0.f)), 1.0);  // still inside (r ≈ 0.69)
}

TEST(EmissionGuide, SceneCoverageWeighsTheLightsByTheirPower) {
    const Vec3 near(0.f, 1.41f, 0.f), far(0.f, 10.41f, 0.f);  // 1 and 10 above the ball's centre
    const double r = 0.4 * std::sqrt(3.0) * 1.001;
    const double c_near = cone_share(r, 1.0), c_far = cone_share(r, 10.0);
    for (float ratio : {1.f, 9.f}) {
        Scene s;
        ball_under_lights(s, {near, far}, {1.f, ratio});
        const EmissionGuide guide(s);
        const double p_near = double(s.light_pmf(0)), p_far = double(s.light_pmf(1));
        EXPECT_NEAR(p_far / p_near, double(ratio), 1e-3 * ratio);  // the same size: power ∝ radiance
        const double want = (p_near * c_near + p_far * c_far) / (p_near + p_far);
        EXPECT_NEAR(caster_coverage(s, guide), want, 2e-3 * want) << "radiance ratio " << ratio;
    }
    Scene unlit_casters;  // no caster: nothing to cover
    {
        unlit_casters.set_materials({Material{Spectrum(0.7f), Spectrum(0.f)}});
        const uint32_t f = unlit_casters.add_mesh("/floor", quad_mesh(Vec3(0.f), Vec3(2, 0, 0), Vec3(0, 0, -2)));
        unlit_casters.add_instance(f, Mat4());
        unlit_casters.add_light(sphere_light(Vec3(0.f, 2.f, 0.f), 0.1f, Spectrum(1.f)));
        unlit_casters.commit();
    }
    const EmissionGuide none(unlit_casters);
    EXPECT_FALSE(none.active());
    EXPECT_EQ(caster_coverage(unlit_casters, none), 0.0);
}
