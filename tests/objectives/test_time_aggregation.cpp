#include "objectives/time_aggregation.hpp"

#include "forward/common/error.hpp"
#include "objective_fd.hpp"

#include "objectives/elastic_energy.hpp"
#include "objectives/kinetic_energy.hpp"
#include <Eigen/Geometry>

using namespace diffipc;

namespace {

/// f(x) = c + sum of the positions: linear, of either sign.
class ShiftedSum : public StateFunctional {
public:
    explicit ShiftedSum(double c)
        : m_c(c)
    {
    }
    std::string name() const override { return "shifted_sum"; }
    double value(const Simulator&, const StateRef& s) const override { return m_c + s.positions.sum(); }
    void add_gradient(const Simulator&, const StateRef& s, const ParameterRequest&, double scale, VectorXd& dx,
        VectorXd&, ParameterGradient&) const override
    {
        gradient_block(dx, s.positions.size()).array() += scale;
    }

private:
    double m_c;
};

std::vector<double> state_values(const StateFunctional& f, const test::Run& run)
{
    std::vector<double> values;
    for (int k = 0; k <= run.steps(); ++k)
        values.push_back(f.value(*run.sim,
            { k, state_time(run.trajectory, k), state_positions(run.trajectory, k),
                state_velocities(run.trajectory, k) }));
    return values;
}

TEST(TimeAggregation, ValuesByHand)
{
    const test::Run run = test::run_scene(test::cantilever_scene(2));
    const std::vector<double> f = state_values(ElasticEnergy(), run);
    ASSERT_EQ(f.size(), 4u);
    const double dt = run.sim->scene().time.dt;
    auto J = [&](TimeMode mode, double p = 8, bool initial = false) {
        return TimeAggregation(std::make_unique<ElasticEnergy>(), mode, p, initial).value(*run.sim, run.trajectory);
    };
    const double tol = 1e-12 * f[3];
    EXPECT_NEAR(J(TimeMode::FINAL), f[3], tol);
    EXPECT_NEAR(J(TimeMode::SUM), f[1] + f[2] + f[3], tol);
    EXPECT_NEAR(J(TimeMode::SUM, 8, true), f[0] + f[1] + f[2] + f[3], tol);
    EXPECT_NEAR(J(TimeMode::TRAPEZOID), dt * (f[0] / 2 + f[1] + f[2] + f[3] / 2), 1e-12 * dt * f[3]);
    EXPECT_NEAR(J(TimeMode::MAX_P, 3), std::cbrt(std::pow(f[1], 3) + std::pow(f[2], 3) + std::pow(f[3], 3)), tol);
    EXPECT_NEAR(J(TimeMode::MAX_P, 1, true), f[0] + f[1] + f[2] + f[3], tol);
    // max_k f_k <= J <= n^{1/p} max_k f_k, and J -> max as p grows (no overflow at p = 500).
    const double f_max = *std::max_element(f.begin() + 1, f.end());
    for (double p : { 2.0, 16.0, 500.0 }) {
        const double Jp = J(TimeMode::MAX_P, p);
        EXPECT_GE(Jp, f_max * (1 - 1e-14));
        EXPECT_LE(Jp, std::pow(3.0, 1 / p) * f_max * (1 + 1e-14));
    }
}

TEST(TimeAggregation, RunWithoutSteps)
{
    const test::Run run = test::run_scene(test::cantilever_scene(2));
    Trajectory t = run.trajectory;
    t.steps.clear();
    const double f0 = state_values(ElasticEnergy(), run)[0];
    EXPECT_DOUBLE_EQ(TimeAggregation(std::make_unique<ElasticEnergy>(), TimeMode::FINAL).value(*run.sim, t), f0);
    EXPECT_EQ(TimeAggregation(std::make_unique<ElasticEnergy>(), TimeMode::SUM).value(*run.sim, t), 0);
    EXPECT_EQ(TimeAggregation(std::make_unique<ElasticEnergy>(), TimeMode::TRAPEZOID).value(*run.sim, t), 0);
    EXPECT_EQ(TimeAggregation(std::make_unique<ElasticEnergy>(), TimeMode::MAX_P).value(*run.sim, t), 0);
}

TEST(TimeAggregation, MaxPNeedsNonnegativeValues)
{
    const test::Run run = test::run_scene(test::cantilever_scene(2));
    const TimeAggregation J(std::make_unique<ShiftedSum>(-1e6), TimeMode::MAX_P, 4);
    EXPECT_THROW(J.value(*run.sim, run.trajectory), ObjectiveDomainError);
    // All zero: J = 0 with a zero gradient rather than NaN.
    const TimeAggregation Z(std::make_unique<ElasticEnergy>(), TimeMode::MAX_P, 4);
    Trajectory t = run.trajectory;
    for (StepRecord& s : t.steps)
        s.positions = flatten(run.sim->mesh().rest_positions);
    EXPECT_EQ(Z.value(*run.sim, t), 0);
    StateSeed seed;
    seed.resize(run.steps());
    Z.add_gradient(*run.sim, t, ParameterRequest {}, 1.0, seed);
    for (const VectorXd& g : seed.positions)
        EXPECT_TRUE(g.size() == 0 || g.allFinite());
    EXPECT_THROW(TimeAggregation(std::make_unique<ElasticEnergy>(), TimeMode::MAX_P, 0.5), std::invalid_argument);
}

TEST(TimeAggregation, ParseTimeMode)
{
    EXPECT_EQ(parse_time_mode("trapezoid", "f"), TimeMode::TRAPEZOID);
    try {
        parse_time_mode("mean", "objective.time");
        FAIL() << "no error";
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), "objective.time");
    }
}

struct ModeCase {
    TimeMode mode;
    double p;
    bool initial;
};

class TimeAggregationGradient : public ::testing::TestWithParam<std::tuple<int, ModeCase>> { };

TEST_P(TimeAggregationGradient, MatchesFiniteDifferences)
{
    const auto [dim, c] = GetParam();
    const test::Run run = test::run_scene(test::cantilever_scene(dim));
    const TimeAggregation position_dependent(std::make_unique<ElasticEnergy>(), c.mode, c.p, c.initial);
    test::check_state_gradient(position_dependent, run);
    test::check_parameter_gradient(position_dependent, run, test::Block::REST_POSITIONS);
    test::check_parameter_gradient(position_dependent, run, test::Block::LAMBDA);
    const TimeAggregation velocity_dependent(std::make_unique<KineticEnergy>(), c.mode, c.p, c.initial);
    test::check_state_gradient(velocity_dependent, run);
    test::check_parameter_gradient(velocity_dependent, run, test::Block::DENSITY);
}

// max_p with p = 4 and 2.5: the states' energies differ by factors ~7, so with p = 8 the
// non-dominant states' weights (f_k / J)^{p-1} fall to ~1e-6 and their derivatives below the
// round-off of J's finite difference (~1e-11 of the dominant state's derivative); a smaller p
// keeps each state's derivative resolvable to 1e-6 relative. The value tests above cover large p.
INSTANTIATE_TEST_SUITE_P(Modes, TimeAggregationGradient,
    ::testing::Combine(::testing::Values(2, 3),
        ::testing::Values(ModeCase { TimeMode::FINAL, 8, false }, ModeCase { TimeMode::SUM, 8, false },
            ModeCase { TimeMode::SUM, 8, true }, ModeCase { TimeMode::TRAPEZOID, 8, false },
            ModeCase { TimeMode::MAX_P, 4, false }, ModeCase { TimeMode::MAX_P, 2.5, true })),
    [](const auto& info) {
        const ModeCase& c = std::get<1>(info.param);
        return std::to_string(std::get<0>(info.param)) + "d_" + to_string(c.mode) + "_p" + std::to_string(int(c.p * 10))
            + (c.initial ? "_initial" : "");
    });

} // namespace

namespace {

/// The run's states replaced by rigid rotations of the rest shape: exact elastic energy 0.
Trajectory rigidly_moved(const test::Run& run)
{
    Trajectory t = run.trajectory;
    const MatrixXd X = run.sim->mesh().rest_positions;
    for (size_t k = 0; k < t.steps.size(); ++k) {
        const double angle = 0.3 + 0.7 * double(k);
        const Eigen::Matrix3d R = Eigen::AngleAxisd(angle, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
        const MatrixXd x = ((X * R.transpose()).rowwise() + Eigen::RowVector3d(0.1, -0.2, 0.3)).eval();
        t.steps[k].positions = flatten(x);
    }
    return t;
}

} // namespace

// A rigidly moving body's elastic energy is 0 up to round-off, and may come out negative
// (-8e-17 J): max_p and non-integer powers take such a value as 0 instead of refusing it.
TEST(TimeAggregation, EnergyZeroUpToRoundOffCountsAsZero)
{
    const test::Run run = test::run_scene(test::cantilever_scene(3, "neo_hookean"));
    const Trajectory t = rigidly_moved(run);
    const ElasticEnergy energy;
    double mu_volume = 0;
    for (Index e = 0; e < run.sim->space().num_elements(); ++e)
        mu_volume += run.sim->space().rest_volume(e) * run.sim->elastic().mu()[e];
    int negative = 0;
    for (int k = 1; k <= run.steps(); ++k) {
        const StateRef state { k, state_time(t, k), state_positions(t, k), state_velocities(t, k) };
        const double f = energy.value(*run.sim, state), r = energy.round_off(*run.sim, state);
        negative += f < 0;
        EXPECT_GE(f, -r) << "state " << k; // the round-off bound holds
        EXPECT_LT(r, 1e-12 * mu_volume); // and allows no more than round-off
    }
    ASSERT_GT(negative, 0) << "no rotation gave a negative round-off energy: the test exercises nothing";
    const TimeAggregation J(std::make_unique<ElasticEnergy>(), TimeMode::MAX_P, 4);
    double value = -1;
    EXPECT_NO_THROW(value = J.value(*run.sim, t));
    EXPECT_GE(value, 0);
    StateSeed seed;
    seed.resize(run.steps());
    EXPECT_NO_THROW(J.add_gradient(*run.sim, t, ParameterRequest {}, 1.0, seed));
    for (const VectorXd& g : seed.positions)
        EXPECT_TRUE(g.size() == 0 || g.allFinite());
    // A value truly below zero, well beyond round-off, is still refused.
    const TimeAggregation shifted(
        std::make_unique<ShiftedSum>(-1e-3 - flatten(run.sim->mesh().rest_positions).sum()), TimeMode::MAX_P, 4);
    Trajectory rest = run.trajectory;
    for (StepRecord& s : rest.steps)
        s.positions = flatten(run.sim->mesh().rest_positions);
    EXPECT_THROW(shifted.value(*run.sim, rest), ObjectiveDomainError);
}
