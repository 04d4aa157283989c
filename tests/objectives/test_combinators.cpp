#include "objectives/combinators.hpp"

#include "objective_fd.hpp"

#include "objectives/center_of_mass.hpp"
#include "objectives/compliance.hpp"
#include "objectives/elastic_energy.hpp"
#include "objectives/kinetic_energy.hpp"
#include "objectives/stress_norm.hpp"
#include "objectives/time_aggregation.hpp"
#include <Eigen/Geometry>

using namespace diffipc;

namespace {

// Frobenius: the von Mises norm of the neo-Hookean Cauchy stress does not depend on lambda in 3D
// (its lambda term is isotropic), and every partial should be exercised here.
std::unique_ptr<Objective> stress(TimeMode mode = TimeMode::SUM)
{
    StressNormOptions o;
    o.norm = StressNormType::FROBENIUS;
    return std::make_unique<TimeAggregation>(std::make_unique<StressNorm>(o), mode);
}
std::unique_ptr<Objective> kinetic()
{
    return std::make_unique<TimeAggregation>(std::make_unique<KineticEnergy>(), TimeMode::TRAPEZOID);
}
std::unique_ptr<Objective> compliance()
{
    return std::make_unique<TimeAggregation>(std::make_unique<Compliance>(), TimeMode::FINAL);
}
std::unique_ptr<Objective> center(int dim)
{
    return std::make_unique<CenterOfMassTracking>(std::vector<int> { 2 }, Positions::Constant(1, dim, 0.3));
}

class CombinatorGradient : public ::testing::TestWithParam<int> { };

TEST_P(CombinatorGradient, WeightedSum)
{
    const int dim = GetParam();
    const test::Run run = test::run_scene(test::cantilever_scene(dim));
    // Weights that bring the terms to similar sizes (2, -0.5, 3): the finite differences of the
    // sum would otherwise see one term's derivative under another term's round-off.
    const double S = stress()->value(*run.sim, run.trajectory), K = kinetic()->value(*run.sim, run.trajectory),
                 C = center(dim)->value(*run.sim, run.trajectory);
    std::vector<WeightedSum::Term> terms;
    terms.push_back({ 2.0 / S, stress() });
    terms.push_back({ -0.5 / K, kinetic() });
    terms.push_back({ 3.0 / C, center(dim) });
    const double expected = 2.0 - 0.5 + 3.0;
    const WeightedSum J(std::move(terms));
    EXPECT_NEAR(J.value(*run.sim, run.trajectory), expected, 1e-12 * std::abs(expected));
    test::check_state_gradient(J, run);
    test::check_all_parameter_gradients(J, run);
}

TEST_P(CombinatorGradient, Power)
{
    const int dim = GetParam();
    const test::Run run = test::run_scene(test::cantilever_scene(dim));
    for (double q : { 2.0, 0.5, 3.0 }) {
        const Power J(q == 3.0 ? compliance() : stress(), q);
        const double G = (q == 3.0 ? compliance() : stress())->value(*run.sim, run.trajectory);
        EXPECT_NEAR(J.value(*run.sim, run.trajectory), std::pow(G, q), 1e-12 * std::pow(std::abs(G), q)) << q;
        test::check_state_gradient(J, run);
        test::check_all_parameter_gradients(J, run);
    }
}

TEST_P(CombinatorGradient, SoftConstraint)
{
    const int dim = GetParam();
    const test::Run run = test::run_scene(test::cantilever_scene(dim));
    const double G = stress()->value(*run.sim, run.trajectory);
    const SoftConstraint upper(stress(), ConstraintSense::UPPER, 0.8 * G, 10);
    const SoftConstraint lower(stress(), ConstraintSense::LOWER, 1.3 * G, 10);
    EXPECT_NEAR(upper.value(*run.sim, run.trajectory), 10 * std::pow(0.2 * G, 2), 1e-10 * G * G);
    EXPECT_NEAR(lower.value(*run.sim, run.trajectory), 10 * std::pow(0.3 * G, 2), 1e-10 * G * G);
    for (const SoftConstraint* J : { &upper, &lower }) {
        test::check_state_gradient(*J, run);
        test::check_all_parameter_gradients(*J, run);
    }
    // Satisfied: zero value, nothing added.
    const SoftConstraint satisfied(stress(), ConstraintSense::UPPER, 1.5 * G, 10);
    EXPECT_EQ(satisfied.value(*run.sim, run.trajectory), 0);
    StateSeed seed;
    seed.resize(run.steps());
    satisfied.add_gradient(*run.sim, run.trajectory, ParameterRequest {}, 1.0, seed);
    for (const VectorXd& g : seed.positions)
        EXPECT_EQ(g.size(), 0);
}

INSTANTIATE_TEST_SUITE_P(Dims, CombinatorGradient, ::testing::Values(2, 3));

TEST(Combinators, InvalidArguments)
{
    EXPECT_THROW(WeightedSum({}), std::invalid_argument);
    EXPECT_THROW(Power(nullptr, 2), std::invalid_argument);
    EXPECT_THROW(SoftConstraint(stress(), ConstraintSense::UPPER, 1.0, 0.0), std::invalid_argument);
    const test::Run run = test::run_scene(test::cantilever_scene(2));
    const WeightedSum negative([] {
        std::vector<WeightedSum::Term> t;
        t.push_back({ -1.0, stress() });
        return t;
    }());
    ASSERT_LT(negative.value(*run.sim, run.trajectory), 0);
    std::vector<WeightedSum::Term> t;
    t.push_back({ -1.0, stress() });
    const Power root(std::make_unique<WeightedSum>(std::move(t)), 0.5);
    EXPECT_THROW(root.value(*run.sim, run.trajectory), ObjectiveDomainError);
}

// A non-integer power of an energy that is zero up to round-off: G counts as 0 (value 0);
// its gradient for q < 1 would be infinite and is refused, for q > 1 it is 0.
TEST(Combinators, PowerOfRoundOffZero)
{
    const test::Run run = test::run_scene(test::cantilever_scene(3, "neo_hookean"));
    Trajectory t = run.trajectory;
    const MatrixXd X = run.sim->mesh().rest_positions;
    // A rigid rotation whose energy comes out below zero (searched, and asserted to exist).
    double G = 0;
    for (int i = 0; i < 50 && !(G < 0); ++i) {
        const Eigen::Matrix3d R
            = Eigen::AngleAxisd(0.1 + 0.37 * i, Eigen::Vector3d(3, 1, 2).normalized()).toRotationMatrix();
        t.steps.back().positions = flatten(MatrixXd(X * R.transpose()));
        G = TimeAggregation(std::make_unique<ElasticEnergy>(), TimeMode::FINAL).value(*run.sim, t);
    }
    ASSERT_LT(G, 0) << "no rotation gave a negative round-off energy";
    for (double q : { 0.5, 1.5 }) {
        const Power J(std::make_unique<TimeAggregation>(std::make_unique<ElasticEnergy>(), TimeMode::FINAL), q);
        EXPECT_EQ(J.value(*run.sim, t), 0.0) << q;
        StateSeed seed;
        seed.resize(run.steps());
        if (q < 1)
            EXPECT_THROW(J.add_gradient(*run.sim, t, ParameterRequest {}, 1.0, seed), ObjectiveDomainError);
        else
            EXPECT_NO_THROW(J.add_gradient(*run.sim, t, ParameterRequest {}, 1.0, seed));
    }
}

} // namespace
