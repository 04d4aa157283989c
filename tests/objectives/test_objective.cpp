#include "objectives/objective.hpp"

#include "objective_fd.hpp"
#include "objectives/elastic_energy.hpp"
#include "objectives/time_aggregation.hpp"

using namespace diffipc;

namespace {

TEST(Objective, StatesOfATrajectory)
{
    const test::Run run = test::run_scene(test::cantilever_scene(2));
    const Trajectory& t = run.trajectory;
    EXPECT_EQ(&state_positions(t, 0), &t.initial_positions);
    EXPECT_EQ(&state_velocities(t, 2), &t.steps[1].velocities);
    EXPECT_DOUBLE_EQ(state_time(t, 0), t.initial_time);
    EXPECT_DOUBLE_EQ(state_time(t, 3), 0.03);
    EXPECT_THROW(state_positions(t, 4), std::out_of_range);
    EXPECT_THROW(state_velocities(t, -1), std::out_of_range);
}

TEST(Objective, GradientBlock)
{
    VectorXd b;
    gradient_block(b, 4)[1] = 2;
    EXPECT_EQ(b, (VectorXd(4) << 0, 2, 0, 0).finished());
    gradient_block(b, 4)[1] += 1;
    EXPECT_EQ(b[1], 3);
    EXPECT_THROW(gradient_block(b, 5), std::logic_error);
}

TEST(Objective, BodyElements)
{
    nlohmann::json s = test::box_scene(2, { 1.0, 0.5 }, { 2, 1 });
    s["bodies"].push_back(test::box_body("second", { 2.0, 0.0 }, { 3.0, 0.5 }, { 1, 1 }));
    const Simulator sim(test::make_scene(s));
    EXPECT_EQ(body_elements(sim.mesh(), -1).size(), 6u);
    EXPECT_EQ(body_elements(sim.mesh(), 0), (std::vector<Index> { 0, 1, 2, 3 }));
    EXPECT_EQ(body_elements(sim.mesh(), 1), (std::vector<Index> { 4, 5 }));
    EXPECT_THROW(body_elements(sim.mesh(), 2), std::out_of_range);
}

TEST(Objective, AddGradientAddsToTheSeed)
{
    const test::Run run = test::run_scene(test::cantilever_scene(3));
    const TimeAggregation J(std::make_unique<ElasticEnergy>(), TimeMode::FINAL);
    ParameterRequest request;
    request.rest_positions = true;
    StateSeed fresh, prefilled;
    fresh.resize(run.steps());
    prefilled.resize(run.steps());
    J.add_gradient(*run.sim, run.trajectory, request, 1.0, fresh);
    const VectorXd ones = VectorXd::Ones(run.dofs());
    prefilled.add_position(run.steps(), ones);
    prefilled.explicit_partials.rest_positions = ones;
    J.add_gradient(*run.sim, run.trajectory, request, 1.0, prefilled);
    EXPECT_TRUE(prefilled.positions.back().isApprox(fresh.positions.back() + ones, 1e-15));
    EXPECT_TRUE(
        prefilled.explicit_partials.rest_positions.isApprox(fresh.explicit_partials.rest_positions + ones, 1e-15));
    // FINAL touches only the last state.
    for (int k = 0; k < run.steps(); ++k)
        EXPECT_EQ(fresh.positions[size_t(k)].size(), 0);
}

} // namespace
