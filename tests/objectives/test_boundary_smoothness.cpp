#include "objectives/boundary_smoothness.hpp"

#include "objective_fd.hpp"

using namespace diffipc;

namespace {

TEST(BoundarySmoothness, StraightBoundaryIsSmoothExceptCorners)
{
    // 2D box: along a straight edge the umbrella vector vanishes; each of the 4 corners
    // contributes |X_c - (X_a + X_b) / 2|^2 with its two neighbours a, b.
    const Scene scene = test::make_scene(test::box_scene(2, { 1.0, 0.5 }, { 2, 1 }));
    const Simulator sim(scene);
    const BoundarySmoothness J(sim.scene());
    // Corner (0,0) with neighbours (0.5,0) and (0,0.5): |(-0.25,-0.25)|^2 = 0.125.
    EXPECT_NEAR(J.value(sim, sim.trajectory()), 4 * 0.125, 1e-15);
}

class BoundarySmoothnessGradient : public ::testing::TestWithParam<int> { };

TEST_P(BoundarySmoothnessGradient, MatchesFiniteDifferences)
{
    const test::Run run = test::run_scene(test::cantilever_scene(GetParam()));
    const BoundarySmoothness J(run.sim->scene(), 0);
    ASSERT_GT(J.value(*run.sim, run.trajectory), 0);
    test::check_state_gradient(J, run); // no state dependence: both sides are zero
    test::check_all_parameter_gradients(J, run);
}

INSTANTIATE_TEST_SUITE_P(Dims, BoundarySmoothnessGradient, ::testing::Values(2, 3));

TEST(BoundarySmoothness, PerBodyAndOtherMeshes)
{
    nlohmann::json s = test::box_scene(2, { 1.0, 0.5 }, { 2, 1 });
    s["bodies"].push_back(test::box_body("second", { 2.0, 0.0 }, { 3.0, 0.5 }, { 2, 1 }));
    const Simulator sim(test::make_scene(s));
    const BoundarySmoothness both(sim.scene()), first(sim.scene(), 0), second(sim.scene(), 1);
    EXPECT_NEAR(both.value(sim, sim.trajectory()),
        first.value(sim, sim.trajectory()) + second.value(sim, sim.trajectory()), 1e-15);
    const Simulator other(test::make_scene(test::box_scene(2, { 1.0, 0.5 }, { 3, 1 })));
    EXPECT_THROW(first.value(other, other.trajectory()), std::invalid_argument);
}

} // namespace
