// The NLopt driver (nlopt_driver.cpp): MMA/CCSAQ refuse equalities, options are checked per
// algorithm, an iteration is an improving evaluation, invalid points and stalls end cleanly.
// The shared problems run in test_optimizer.cpp.

#include "forward/common/error.hpp"
#include "shape_opt/optimizer/optimizer.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

using namespace diffipc;

namespace {

constexpr double INF = std::numeric_limits<double>::infinity();

/// |x - (2, 2)|^2 subject to x0 + x1 = 1 (equality) and x0 - x1 <= 0.5 (inactive): the
/// minimum is (0.5, 0.5).
class WithEquality : public OptimizationProblem {
public:
    Index size() const override { return 2; }
    int inequalities() const override { return 1; }
    int equalities() const override { return 1; }
    bool evaluate(const VectorXd& x, OptimizationValues& out) override
    {
        out.f = (x - Eigen::Vector2d(2, 2)).squaredNorm();
        out.gradient = 2 * (x - Eigen::Vector2d(2, 2));
        out.equality = VectorXd::Constant(1, x[0] + x[1] - 1);
        out.equality_jacobian = Eigen::RowVector2d(1, 1);
        out.inequality = VectorXd::Constant(1, x[0] - x[1] - 0.5);
        out.inequality_jacobian = Eigen::RowVector2d(1, -1);
        return true;
    }
};

/// Rosenbrock's 2D function; records f at the iterates and which points are invalid.
class Rosenbrock2 : public OptimizationProblem {
public:
    Index size() const override { return 2; }
    bool evaluate(const VectorXd& x, OptimizationValues& out) override
    {
        ++evaluations;
        if (only_start_valid && x != Eigen::Vector2d(-1.2, 1)) {
            ++failures;
            return false;
        }
        const double a = x[0], b = x[1], r = b - a * a;
        out.f = 100 * r * r + (1 - a) * (1 - a);
        out.gradient = Eigen::Vector2d(-400 * a * r - 2 * (1 - a), 200 * r);
        return true;
    }
    bool iteration(const IterationInfo& info) override
    {
        fs.push_back(info.values->f);
        return true;
    }
    bool only_start_valid = false;
    int evaluations = 0, failures = 0;
    std::vector<double> fs;
};

OptimizerSettings settings(OptimizerAlgorithm a)
{
    OptimizerSettings s;
    s.algorithm = a;
    s.gradient_tolerance = 1e-9;
    s.relative_gradient_tolerance = 0;
    s.max_iterations = 20000;
    return s;
}

const VectorXd START = Eigen::Vector2d(-1.2, 1);

std::string error_field(const OptimizerSettings& s)
{
    Rosenbrock2 p;
    try {
        minimize(p, START, s);
    } catch (const InputError& e) {
        return e.field();
    }
    return "";
}

} // namespace

TEST(NloptDriver, CcsaRefusesEqualities)
{
    WithEquality p;
    for (auto a : { OptimizerAlgorithm::MMA, OptimizerAlgorithm::CCSAQ }) {
        try {
            minimize(p, VectorXd::Zero(2), settings(a));
            FAIL();
        } catch (const InputError& e) {
            EXPECT_EQ(e.field(), "optimizer.algorithm");
            EXPECT_NE(std::string(e.what()).find("use ipopt or slsqp"), std::string::npos) << e.what();
        }
    }
    // SLSQP takes it: the minimum (0.5, 0.5) to 1e-6 (x_tolerance 1e-12; the gradient rules
    // do not apply with constraints).
    OptimizerSettings s = settings(OptimizerAlgorithm::SLSQP);
    s.x_tolerance = 1e-12;
    s.constraint_tolerance = 1e-10;
    const OptimizerResult r = minimize(p, VectorXd::Zero(2), s);
    EXPECT_LT((r.x - Eigen::Vector2d(0.5, 0.5)).lpNorm<Eigen::Infinity>(), 1e-6) << r.message;
}

TEST(NloptDriver, OptionsPerAlgorithm)
{
    OptimizerSettings s = settings(OptimizerAlgorithm::MMA);
    s.options["inner_maxeval"] = "10";
    s.options["dual_algorithm"] = "LD_MMA";
    s.options["dual_ftol_rel"] = "1e-12";
    s.options["verbosity"] = "0";
    EXPECT_EQ(error_field(s), "");

    s.options = { { "dual_algorithm", "nonsense" } };
    EXPECT_EQ(error_field(s), "optimizer.options.dual_algorithm");
    s.options = { { "inner_maxeval", "-1" } };
    EXPECT_EQ(error_field(s), "optimizer.options.inner_maxeval");
    s.options = { { "xtol_rel", "abc" } };
    EXPECT_EQ(error_field(s), "optimizer.options.xtol_rel");
    s.options = { { "mu_strategy", "adaptive" } }; // an Ipopt option
    EXPECT_EQ(error_field(s), "optimizer.options.mu_strategy");

    s = settings(OptimizerAlgorithm::SLSQP);
    s.options = { { "inner_maxeval", "10" } }; // CCSA only
    EXPECT_EQ(error_field(s), "optimizer.options.inner_maxeval");
    s.options = { { "stopval", "-inf" }, { "ftol_abs", "0" }, { "xtol_rel", "0" } };
    EXPECT_EQ(error_field(s), "");
}

TEST(NloptDriver, MaxevalIsAnIterationBudget)
{
    OptimizerSettings s = settings(OptimizerAlgorithm::SLSQP);
    s.options["maxeval"] = "10";
    Rosenbrock2 p;
    const OptimizerResult r = minimize(p, START, s);
    EXPECT_EQ(r.reason, StopReason::ITERATION_BUDGET) << r.message;
    EXPECT_NE(r.message.find("MAXEVAL_REACHED (10 evaluations)"), std::string::npos) << r.message;
    EXPECT_LE(p.evaluations, 10); // NLopt's calls at x0 (the first) and repeated points come from the cache
}

// An iteration is an evaluation that improves the best point: f strictly decreases from one
// callback to the next, and there are as many callbacks as iterations (plus the start's).
TEST(NloptDriver, IterationsImprove)
{
    for (auto a : { OptimizerAlgorithm::MMA, OptimizerAlgorithm::CCSAQ, OptimizerAlgorithm::SLSQP }) {
        Rosenbrock2 p;
        const OptimizerResult r = minimize(p, START, settings(a));
        ASSERT_EQ(int(p.fs.size()), r.iterations + 1) << to_string(a);
        for (size_t k = 1; k < p.fs.size(); ++k)
            EXPECT_LT(p.fs[k], p.fs[k - 1]) << to_string(a) << " iteration " << k;
        EXPECT_LT(r.evaluations - r.iterations, r.evaluations) << "some evaluations are not iterations";
    }
}

// Every point but the start is invalid: NLopt gets large finite values (never NaN), finds no
// better point and the run ends cleanly at the start (no improvement in 200 evaluations, or
// NLopt's own stop), with every other point rejected.
TEST(NloptDriver, EverythingButTheStartInvalid)
{
    for (auto a : { OptimizerAlgorithm::MMA, OptimizerAlgorithm::CCSAQ, OptimizerAlgorithm::SLSQP }) {
        Rosenbrock2 p;
        p.only_start_valid = true;
        const OptimizerResult r = minimize(p, START, settings(a));
        EXPECT_EQ(r.x, START) << to_string(a);
        EXPECT_EQ(r.rejected, p.failures) << to_string(a); // CCSA may come back to the start
        EXPECT_GT(r.rejected, 0) << to_string(a);
        EXPECT_LE(r.rejected, 201) << to_string(a);
        EXPECT_NE(r.reason, StopReason::GRADIENT_TOLERANCE) << to_string(a) << ": " << r.message;
        EXPECT_TRUE(std::isfinite(r.values.f));
    }
}

// An infeasible start: the iterations before the first feasible point are those that reduce the
// violation; the run ends feasible at the constrained minimum (0.5, sqrt(1.75)) of
// (x0 - 2)^2 + (x1 - 2)^2 subject to x0^2 + x1^2 <= 2, x0 <= 0.5, to 1e-6.
TEST(NloptDriver, InfeasibleStart)
{
    class Circle : public OptimizationProblem {
    public:
        Index size() const override { return 2; }
        int inequalities() const override { return 1; }
        bool evaluate(const VectorXd& x, OptimizationValues& out) override
        {
            out.f = (x - Eigen::Vector2d(2, 2)).squaredNorm();
            out.gradient = 2 * (x - Eigen::Vector2d(2, 2));
            out.inequality = VectorXd::Constant(1, x.squaredNorm() - 2);
            out.inequality_jacobian = 2 * x.transpose();
            return true;
        }
    };
    for (auto a : { OptimizerAlgorithm::MMA, OptimizerAlgorithm::CCSAQ, OptimizerAlgorithm::SLSQP }) {
        Circle p;
        OptimizerSettings s = settings(a);
        s.lower = Eigen::Vector2d(-5, -5);
        s.upper = Eigen::Vector2d(0.5, 5);
        s.x_tolerance = 1e-12;
        s.constraint_tolerance = 1e-9;
        const OptimizerResult r = minimize(p, Eigen::Vector2d(-2, 3), s); // |x|^2 = 13 > 2
        EXPECT_LT((r.x - Eigen::Vector2d(0.5, std::sqrt(1.75))).lpNorm<Eigen::Infinity>(), 1e-6)
            << to_string(a) << ": " << r.message << " " << r.x.transpose();
        EXPECT_LE(r.max_violation, 1e-9);
    }
    (void)INF;
}
