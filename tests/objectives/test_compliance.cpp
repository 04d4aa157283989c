#include "objectives/compliance.hpp"

#include "objective_fd.hpp"
#include "objectives/time_aggregation.hpp"

using namespace diffipc;

namespace {

TEST(Compliance, ValueIsWorkOfTheExternalForces)
{
    for (int dim : { 2, 3 }) {
        const test::Run run = test::run_scene(test::cantilever_scene(dim));
        const Compliance f;
        const VectorXd X = flatten(run.sim->mesh().rest_positions);
        for (int k = 0; k <= run.steps(); ++k) {
            const double t = state_time(run.trajectory, k);
            const VectorXd& x = state_positions(run.trajectory, k);
            const double expected = run.sim->external_forces(t).dot(x - X);
            EXPECT_NEAR(f.value(*run.sim, { k, t, x, state_velocities(run.trajectory, k) }), expected,
                1e-12 * std::abs(expected));
        }
    }
}

TEST(Compliance, TractionDependsOnTime)
{
    // The scene's traction grows with t; the functional must use each state's own time.
    const test::Run run = test::run_scene(test::cantilever_scene(2));
    EXPECT_NE(run.sim->external_forces(state_time(run.trajectory, 1)),
        run.sim->external_forces(state_time(run.trajectory, 3)));
}

class ComplianceGradient : public ::testing::TestWithParam<int> { };

TEST_P(ComplianceGradient, MatchesFiniteDifferences)
{
    const test::Run run = test::run_scene(test::cantilever_scene(GetParam()));
    // Trapezoid in time: every state with its own time and weight.
    const TimeAggregation J(std::make_unique<Compliance>(), TimeMode::TRAPEZOID);
    ASSERT_NE(J.value(*run.sim, run.trajectory), 0);
    test::check_state_gradient(J, run);
    // Rest positions through u = x - X, the lumped masses (gravity) and the loaded facet
    // areas (traction); density through the masses; no Lame dependence.
    test::check_all_parameter_gradients(J, run);
}

INSTANTIATE_TEST_SUITE_P(Dims, ComplianceGradient, ::testing::Values(2, 3));

} // namespace
