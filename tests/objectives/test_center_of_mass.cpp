#include "objectives/center_of_mass.hpp"

#include "objective_fd.hpp"

using namespace diffipc;

namespace {

TEST(CenterOfMass, MatchesLumpedMasses)
{
    for (int dim : { 2, 3 }) {
        const test::Run run = test::run_scene(test::cantilever_scene(dim));
        const VectorXd& m = run.sim->inertia().lumped_masses();
        const VectorXd& x = state_positions(run.trajectory, 2);
        VectorXd expected = VectorXd::Zero(dim);
        for (Index v = 0; v < m.size(); ++v)
            expected += m[v] * x.segment(v * dim, dim);
        expected /= m.sum();
        const CenterOfMassTracking J({ 2 }, Positions::Zero(1, dim));
        EXPECT_TRUE(J.center(*run.sim, x).isApprox(expected, 1e-14)) << dim;
        EXPECT_NEAR(J.value(*run.sim, run.trajectory), 0.5 * expected.squaredNorm(), 1e-14);
    }
}

class CenterOfMassGradient : public ::testing::TestWithParam<int> { };

TEST_P(CenterOfMassGradient, MatchesFiniteDifferences)
{
    const int dim = GetParam();
    const test::Run run = test::run_scene(test::cantilever_scene(dim));
    const std::vector<int> steps = { 0, 1, 3 };
    Positions targets(3, dim);
    for (int s = 0; s < 3; ++s) {
        const CenterOfMassTracking probe({ steps[size_t(s)] }, Positions::Zero(1, dim));
        targets.row(s) = probe.center(*run.sim, state_positions(run.trajectory, steps[size_t(s)])).transpose()
            + 0.01 * test::random_vector(dim, unsigned(60 + s)).transpose();
    }
    const CenterOfMassTracking J(steps, targets, 4.0);
    test::check_state_gradient(J, run);
    // The centre moves with the masses: rest positions and density partials.
    test::check_all_parameter_gradients(J, run);
    // Part of the body (its first half of elements) only.
    std::vector<Index> half;
    for (Index e = 0; e < run.sim->mesh().num_elements() / 2; ++e)
        half.push_back(e);
    const CenterOfMassTracking Jh(steps, targets, 1.0, half);
    test::check_state_gradient(Jh, run);
    test::check_all_parameter_gradients(Jh, run);
}

INSTANTIATE_TEST_SUITE_P(Dims, CenterOfMassGradient, ::testing::Values(2, 3));

} // namespace
