#include "objectives/volume.hpp"

#include "objective_fd.hpp"
#include "objectives/time_aggregation.hpp"

using namespace diffipc;

namespace {

TEST(Volume, SumOfSignedElementVolumes)
{
    for (int dim : { 2, 3 }) {
        const test::Run run = test::run_scene(test::cantilever_scene(dim));
        const Mesh& mesh = run.sim->mesh();
        const Volume f;
        // At rest: the box's volume.
        const VectorXd X = flatten(mesh.rest_positions);
        const double box = dim == 2 ? 0.25 : 0.25 * 0.25;
        EXPECT_NEAR(f.value(*run.sim, { 0, 0.0, X, X }), box, 1e-14);
        const VectorXd& x = state_positions(run.trajectory, run.steps());
        double expected = 0;
        for (Index e = 0; e < mesh.num_elements(); ++e)
            expected += signed_volume(unflatten(x, dim), mesh.elements, e);
        EXPECT_NEAR(f.value(*run.sim, { run.steps(), 0.0, x, x }), expected, 1e-14) << dim;
    }
}

class VolumeGradient : public ::testing::TestWithParam<int> { };

TEST_P(VolumeGradient, MatchesFiniteDifferences)
{
    const test::Run run = test::run_scene(test::cantilever_scene(GetParam()));
    std::vector<Index> half;
    for (Index e = 0; e < run.sim->mesh().num_elements() / 2; ++e)
        half.push_back(e);
    std::vector<std::unique_ptr<Objective>> objectives;
    objectives.push_back(std::make_unique<TimeAggregation>(std::make_unique<Volume>(), TimeMode::SUM, 8, true));
    objectives.push_back(std::make_unique<TimeAggregation>(std::make_unique<Volume>(half), TimeMode::MAX_P, 4));
    for (const auto& J : objectives) {
        test::check_state_gradient(*J, run);
        // The current volume is det(D_s)/d!, a function of x alone: the rest-position partial is
        // identically zero and the finite difference of value() is round-off (~1e-16 |J| / 1e-7 m).
        // The floor |J| makes the check absolute at 1e-6 |J|, while a missing or spurious term
        // would be of order |J| / (0.25 m) per unit direction.
        test::check_parameter_gradient(*J, run, test::Block::REST_POSITIONS, 23, 1e-6, 1.0);
        test::check_parameter_gradient(*J, run, test::Block::MU);
        test::check_parameter_gradient(*J, run, test::Block::DENSITY);
    }
}

INSTANTIATE_TEST_SUITE_P(Dims, VolumeGradient, ::testing::Values(2, 3));

TEST(Volume, RestVolumeIsTheMaterialsVolumeAtEveryState)
{
    for (int dim : { 2, 3 }) {
        const test::Run run = test::run_scene(test::cantilever_scene(dim));
        const Mesh& mesh = run.sim->mesh();
        const Volume rest({}, true);
        double expected = 0; // independently, from the rest mesh's elements
        for (Index e = 0; e < mesh.num_elements(); ++e)
            expected += signed_volume(mesh.rest_positions, mesh.elements, e);
        const VectorXd& x = state_positions(run.trajectory, run.steps());
        EXPECT_NEAR(rest.value(*run.sim, { run.steps(), 0.0, x, x }), expected, 1e-14) << dim;
        EXPECT_NEAR(expected, dim == 2 ? 0.25 : 0.25 * 0.25, 1e-14);
    }
}

class RestVolumeGradient : public ::testing::TestWithParam<int> { };

TEST_P(RestVolumeGradient, IsAnExplicitShapeDerivative)
{
    const test::Run run = test::run_scene(test::cantilever_scene(GetParam()));
    std::vector<Index> half;
    for (Index e = 0; e < run.sim->mesh().num_elements() / 2; ++e)
        half.push_back(e);
    const TimeAggregation J(std::make_unique<Volume>(half, true), TimeMode::FINAL);
    // No state dependence (the state check sees a zero gradient and a zero difference), and the
    // rest-position partial against central differences of value().
    test::check_state_gradient(J, run);
    test::check_parameter_gradient(J, run, test::Block::REST_POSITIONS);
    test::check_parameter_gradient(J, run, test::Block::MU);
}

INSTANTIATE_TEST_SUITE_P(Dims, RestVolumeGradient, ::testing::Values(2, 3));

} // namespace
