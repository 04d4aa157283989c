#include "objectives/kinetic_energy.hpp"

#include "objective_fd.hpp"
#include "objectives/time_aggregation.hpp"

using namespace diffipc;

namespace {

class KineticEnergyTest : public ::testing::TestWithParam<std::tuple<int, std::string>> { };

TEST_P(KineticEnergyTest, ValueIsHalfVMV)
{
    const auto [dim, mass] = GetParam();
    const test::Run run = test::run_scene(test::cantilever_scene(dim, "neo_hookean", mass));
    ASSERT_EQ(run.sim->inertia().consistent(), mass == "consistent");
    const KineticEnergy f;
    for (int k = 0; k <= run.steps(); ++k) {
        const VectorXd& v = state_velocities(run.trajectory, k);
        const double expected = 0.5 * v.dot(run.sim->inertia().apply_mass(v));
        EXPECT_GT(expected, 0);
        EXPECT_NEAR(f.value(*run.sim, { k, 0.0, state_positions(run.trajectory, k), v }), expected, 1e-12 * expected);
    }
}

TEST_P(KineticEnergyTest, GradientMatchesFiniteDifferences)
{
    const auto [dim, mass] = GetParam();
    const test::Run run = test::run_scene(test::cantilever_scene(dim, "neo_hookean", mass));
    const TimeAggregation J(std::make_unique<KineticEnergy>(), TimeMode::TRAPEZOID);
    test::check_state_gradient(J, run);
    test::check_all_parameter_gradients(J, run);
    std::vector<Index> some = { 0, 3, 5 };
    const TimeAggregation Js(std::make_unique<KineticEnergy>(some), TimeMode::MAX_P, 6, true);
    test::check_state_gradient(Js, run);
    test::check_parameter_gradient(Js, run, test::Block::DENSITY);
    test::check_parameter_gradient(Js, run, test::Block::REST_POSITIONS);
}

INSTANTIATE_TEST_SUITE_P(Masses, KineticEnergyTest,
    ::testing::Combine(::testing::Values(2, 3), ::testing::Values("lumped", "consistent")),
    [](const auto& info) { return std::to_string(std::get<0>(info.param)) + "d_" + std::get<1>(info.param); });

} // namespace
