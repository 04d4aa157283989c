#include "objectives/elastic_energy.hpp"

#include "objective_fd.hpp"
#include "objectives/time_aggregation.hpp"

using namespace diffipc;

namespace {

class ElasticEnergyGradient : public ::testing::TestWithParam<std::tuple<int, std::string>> { };

TEST_P(ElasticEnergyGradient, MatchesFiniteDifferences)
{
    const auto [dim, model] = GetParam();
    const test::Run run = test::run_scene(test::cantilever_scene(dim, model));
    const TimeAggregation J(std::make_unique<ElasticEnergy>(), TimeMode::SUM, 8, true);
    ASSERT_GT(J.value(*run.sim, run.trajectory), 0);
    test::check_state_gradient(J, run);
    test::check_all_parameter_gradients(J, run);
}

INSTANTIATE_TEST_SUITE_P(Models, ElasticEnergyGradient,
    ::testing::Combine(
        ::testing::Values(2, 3), ::testing::Values("linear", "stvk", "neo_hookean", "stable_neo_hookean")),
    [](const auto& info) { return std::to_string(std::get<0>(info.param)) + "d_" + std::get<1>(info.param); });

TEST(ElasticEnergy, EqualsTheElasticPotential)
{
    for (int dim : { 2, 3 }) {
        const test::Run run = test::run_scene(test::cantilever_scene(dim));
        const ElasticEnergy f;
        for (int k = 0; k <= run.steps(); ++k) {
            const VectorXd& x = state_positions(run.trajectory, k);
            const double expected = run.sim->elastic().value(x);
            EXPECT_NEAR(f.value(*run.sim, { k, 0.0, x, state_velocities(run.trajectory, k) }), expected,
                1e-12 * std::abs(expected))
                << dim << " " << k;
        }
    }
}

TEST(ElasticEnergy, ElementSubsetGradient)
{
    const test::Run run = test::run_scene(test::cantilever_scene(3, "stvk"));
    std::vector<Index> elements;
    for (Index e = 1; e < run.sim->mesh().num_elements(); e += 3)
        elements.push_back(e);
    const TimeAggregation J(std::make_unique<ElasticEnergy>(elements), TimeMode::FINAL);
    test::check_state_gradient(J, run);
    test::check_parameter_gradient(J, run, test::Block::REST_POSITIONS);
    test::check_parameter_gradient(J, run, test::Block::MU);
}

} // namespace
