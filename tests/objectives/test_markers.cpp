#include "objectives/markers.hpp"

#include "objective_fd.hpp"

using namespace diffipc;

namespace {

/// Markers: the last vertex and the centroid-ish point of element 2; targets near the states.
MarkerTracking make_markers(const test::Run& run, std::vector<int> steps)
{
    const Mesh& mesh = run.sim->mesh();
    const int d = mesh.dim;
    std::vector<double> w(size_t(d + 1), 0.0);
    for (int a = 0; a <= d; ++a)
        w[size_t(a)] = 0.1 + 0.2 * a;
    double sum = 0;
    for (double wi : w)
        sum += wi;
    for (double& wi : w)
        wi /= sum;
    std::vector<MarkerPoint> markers = { MarkerPoint::vertex(mesh.num_vertices() - 1),
        MarkerPoint::barycentric(mesh, 2, w), MarkerPoint::vertex(1) };
    std::vector<Positions> targets;
    for (size_t s = 0; s < steps.size(); ++s) {
        MarkerTracking probe(markers, { steps[s] }, { Positions::Zero(3, d) });
        targets.push_back(probe.positions(state_positions(run.trajectory, steps[s]), d)
            + 0.01 * unflatten(test::random_vector(3 * d, unsigned(40 + s)), d));
    }
    VectorXd weights(3);
    weights << 1.0, 2.5, 0.5;
    return MarkerTracking(markers, steps, targets, weights);
}

TEST(Markers, ValueByHand)
{
    const test::Run run = test::run_scene(test::cantilever_scene(2));
    const Mesh& mesh = run.sim->mesh();
    const Index v = mesh.num_vertices() - 1;
    Positions target(1, 2);
    target << 1.1, 0.2;
    const MarkerTracking J({ MarkerPoint::vertex(v) }, { 2 }, { target }, VectorXd::Constant(1, 3.0));
    const VectorXd& x = state_positions(run.trajectory, 2);
    const double expected = 0.5 * 3.0 * (x.segment(v * 2, 2) - target.row(0).transpose()).squaredNorm();
    EXPECT_DOUBLE_EQ(J.value(*run.sim, run.trajectory), expected);
}

TEST(Markers, BarycentricPointInterpolates)
{
    const test::Run run = test::run_scene(test::cantilever_scene(3));
    const Mesh& mesh = run.sim->mesh();
    const MarkerPoint p = MarkerPoint::barycentric(mesh, 4, { 0.25, 0.25, 0.25, 0.25 });
    const MarkerTracking J({ p }, { 0 }, { Positions::Zero(1, 3) });
    const VectorXd& x = state_positions(run.trajectory, 3);
    Eigen::RowVector3d centroid = Eigen::RowVector3d::Zero();
    for (int a = 0; a < 4; ++a)
        centroid += 0.25 * x.segment<3>(mesh.elements(4, a) * 3).transpose();
    EXPECT_TRUE(J.positions(x, 3).row(0).isApprox(centroid, 1e-15));
    EXPECT_THROW(MarkerPoint::barycentric(mesh, 4, { 0.5, 0.25, 0.25, 0.25 }), std::invalid_argument);
    EXPECT_THROW(MarkerPoint::barycentric(mesh, 4, { 0.5, 0.5 }), std::invalid_argument);
}

class MarkersGradient : public ::testing::TestWithParam<int> { };

TEST_P(MarkersGradient, MatchesFiniteDifferences)
{
    const test::Run run = test::run_scene(test::cantilever_scene(GetParam()));
    const MarkerTracking every = make_markers(run, { 1, 2, 3 });
    const MarkerTracking listed = make_markers(run, { 0, 2 });
    for (const Objective* J : { static_cast<const Objective*>(&every), static_cast<const Objective*>(&listed) }) {
        ASSERT_GT(J->value(*run.sim, run.trajectory), 0);
        test::check_state_gradient(*J, run);
        // The weights are fixed: no explicit partial anywhere (the value does not change).
        test::check_all_parameter_gradients(*J, run);
    }
}

INSTANTIATE_TEST_SUITE_P(Dims, MarkersGradient, ::testing::Values(2, 3));

TEST(Markers, StepBeyondTheTrajectoryThrows)
{
    const test::Run run = test::run_scene(test::cantilever_scene(2));
    const MarkerTracking J({ MarkerPoint::vertex(0) }, { 4 }, { Positions::Zero(1, 2) });
    EXPECT_THROW(J.value(*run.sim, run.trajectory), std::out_of_range);
}

} // namespace
