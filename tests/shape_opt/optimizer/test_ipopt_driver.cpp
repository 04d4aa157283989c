// The Ipopt driver (ipopt_driver.cpp): options passed through and checked, one evaluation per
// point, no output by default, statuses mapped. The shared problems run in test_optimizer.cpp.

#include "forward/common/error.hpp"
#include "shape_opt/optimizer/optimizer.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <set>
#include <vector>

using namespace diffipc;

namespace {

/// Rosenbrock's 2D function, recording every evaluated point.
class Rosenbrock2 : public OptimizationProblem {
public:
    Index size() const override { return 2; }
    bool evaluate(const VectorXd& x, OptimizationValues& out) override
    {
        evaluated.push_back(x);
        const double a = x[0], b = x[1], r = b - a * a;
        out.f = 100 * r * r + (1 - a) * (1 - a);
        out.gradient = Eigen::Vector2d(-400 * a * r - 2 * (1 - a), 200 * r);
        return true;
    }
    std::vector<VectorXd> evaluated;
};

/// x <= -1 and x >= 1 at once: no feasible point.
class Contradiction : public OptimizationProblem {
public:
    Index size() const override { return 1; }
    int inequalities() const override { return 2; }
    bool evaluate(const VectorXd& x, OptimizationValues& out) override
    {
        out.f = x[0] * x[0];
        out.gradient = 2 * x;
        out.inequality = Eigen::Vector2d(x[0] + 1, 1 - x[0]);
        out.inequality_jacobian = Eigen::Vector2d(1, -1);
        return true;
    }
};

OptimizerSettings ipopt()
{
    OptimizerSettings s;
    s.algorithm = OptimizerAlgorithm::IPOPT;
    s.gradient_tolerance = 1e-9;
    s.relative_gradient_tolerance = 0;
    return s;
}

const VectorXd START = Eigen::Vector2d(-1.2, 1);

/// The field of the InputError minimize() throws ("" if none), and its message in `what`.
std::string error_field(const OptimizerSettings& s, std::string* what = nullptr)
{
    Rosenbrock2 p;
    try {
        minimize(p, START, s);
    } catch (const InputError& e) {
        if (what)
            *what = e.what();
        return e.field();
    }
    return "";
}

} // namespace

TEST(IpoptDriver, SolvesQuietlyWithTheStatusInTheMessage)
{
    Rosenbrock2 p;
    testing::internal::CaptureStdout();
    const OptimizerResult r = minimize(p, START, ipopt());
    const std::string output = testing::internal::GetCapturedStdout();
    EXPECT_EQ(output, ""); // print_level 0, no banner
    EXPECT_EQ(r.reason, StopReason::GRADIENT_TOLERANCE);
    EXPECT_NE(r.message.find("Solve_Succeeded"), std::string::npos) << r.message;
    EXPECT_LT((r.x - Eigen::Vector2d(1, 1)).lpNorm<Eigen::Infinity>(), 1e-6);
}

// Ipopt asks for f, grad f (and g, jac g) separately: each point is evaluated once.
TEST(IpoptDriver, OneEvaluationPerPoint)
{
    Rosenbrock2 p;
    const OptimizerResult r = minimize(p, START, ipopt());
    std::set<std::vector<double>> distinct;
    for (const VectorXd& x : p.evaluated)
        distinct.insert(std::vector<double>(x.data(), x.data() + x.size()));
    EXPECT_EQ(distinct.size(), p.evaluated.size());
    EXPECT_EQ(r.evaluations, int(p.evaluated.size()));
}

TEST(IpoptDriver, OptionsOverrideTheSettings)
{
    {
        OptimizerSettings s = ipopt();
        s.options["max_iter"] = "3"; // an integer option
        Rosenbrock2 p;
        const OptimizerResult r = minimize(p, START, s);
        EXPECT_EQ(r.reason, StopReason::ITERATION_BUDGET) << r.message;
        EXPECT_EQ(r.iterations, 3);
        EXPECT_NE(r.message.find("Maximum_Iterations_Exceeded"), std::string::npos) << r.message;
    }
    {
        OptimizerSettings s = ipopt();
        s.options["mu_strategy"] = "adaptive"; // a string option
        s.options["tol"] = "1e-10"; // a numeric option
        s.options["limited_memory_max_history"] = "20";
        Rosenbrock2 p;
        const OptimizerResult r = minimize(p, START, s);
        EXPECT_EQ(r.reason, StopReason::GRADIENT_TOLERANCE) << r.message;
        EXPECT_LT((r.x - Eigen::Vector2d(1, 1)).lpNorm<Eigen::Infinity>(), 1e-6);
    }
}

TEST(IpoptDriver, RejectedOptionsNameTheirField)
{
    OptimizerSettings s = ipopt();
    s.options["no_such_option"] = "1";
    EXPECT_EQ(error_field(s), "optimizer.options.no_such_option");

    s.options.clear();
    s.options["max_iter"] = "many";
    EXPECT_EQ(error_field(s), "optimizer.options.max_iter");

    s.options.clear();
    s.options["tol"] = "-1"; // out of its range (tol > 0)
    EXPECT_EQ(error_field(s), "optimizer.options.tol");

    s.options.clear();
    s.options["mu_strategy"] = "fast";
    std::string what;
    EXPECT_EQ(error_field(s, &what), "optimizer.options.mu_strategy");
    EXPECT_NE(what.find("\"monotone\""), std::string::npos) << what; // lists the valid values
}

TEST(IpoptDriver, InfeasibleProblem)
{
    Contradiction p;
    OptimizerSettings s = ipopt();
    s.max_iterations = 500;
    const OptimizerResult r = minimize(p, VectorXd::Zero(1), s);
    EXPECT_EQ(r.reason, StopReason::INFEASIBLE) << r.message;
    EXPECT_GT(r.max_violation, 0.5);
    EXPECT_NE(r.message.find("no point within constraint_tolerance"), std::string::npos) << r.message;
}

// The callback sees Ipopt's iterates with the dual infeasibility as gradient_norm; the first is
// the start, which lies inside the box (Ipopt would push a start on a bound inside first).
TEST(IpoptDriver, IterationsAreIpoptsIterates)
{
    class Recording : public Rosenbrock2 {
    public:
        bool iteration(const IterationInfo& info) override
        {
            iterations.push_back(info.iteration);
            return true;
        }
        std::vector<int> iterations;
    } p;
    const OptimizerResult r = minimize(p, START, ipopt());
    ASSERT_FALSE(p.iterations.empty());
    EXPECT_EQ(p.iterations.front(), 0);
    EXPECT_EQ(p.iterations.back(), r.iterations);
    for (size_t k = 0; k < p.iterations.size(); ++k)
        EXPECT_EQ(p.iterations[k], int(k));
}

namespace {
/// f = (x - 3)^2 with every x > 1 invalid (evaluate() returns false): the minimum lies beyond
/// the valid designs, which Ipopt does not know as a constraint.
class BeyondTheValidDesigns : public OptimizationProblem {
public:
    Index size() const override { return 1; }
    bool evaluate(const VectorXd& x, OptimizationValues& out) override
    {
        if (x[0] > 1)
            return false;
        out.f = (x[0] - 3) * (x[0] - 3);
        out.gradient = VectorXd::Constant(1, 2 * (x[0] - 3));
        return true;
    }
};
} // namespace

// Before: Ipopt cut every step at the rejected points until the steps were 1e-11 and ran to
// its iteration budget (a beam's shape: 982 of 1050 trials rejected). Now five iterations in a
// row with rejections and steps below 1e-9 of x end the run as a stalled line search, at a
// valid point next to the boundary.
TEST(IpoptDriver, StepsThatVanishAtRejectedDesignsEndTheRun)
{
    BeyondTheValidDesigns p;
    OptimizerSettings s = ipopt();
    s.max_iterations = 3000;
    const OptimizerResult r = minimize(p, VectorXd::Zero(1), s);
    EXPECT_EQ(r.reason, StopReason::LINE_SEARCH_STALLED) << r.message;
    EXPECT_LT(r.iterations, 3000);
    EXPECT_GT(r.rejected, 5);
    EXPECT_LE(r.x[0], 1.0);
    EXPECT_GT(r.x[0], 0.9) << r.message;
}

// Our mumps_mem_percent (100, where Ipopt's is 1000) changes MUMPS's workspace only: Ipopt's
// default, given as an option, evaluates the same points in the same order, bit for bit, on
// Rosenbrock's function with bounds and a circle that is active at the optimum.
TEST(IpoptDriver, TheMumpsWorkspaceLeavesEveryPointAsItWas)
{
    class Circle : public Rosenbrock2 {
    public:
        int inequalities() const override { return 1; }
        bool evaluate(const VectorXd& x, OptimizationValues& out) override
        {
            Rosenbrock2::evaluate(x, out);
            out.inequality = VectorXd::Constant(1, x.squaredNorm() - 1.5);
            out.inequality_jacobian = 2 * x.transpose();
            return true;
        }
    };
    OptimizerSettings s = ipopt();
    s.lower = Eigen::Vector2d(-2, -2);
    s.upper = Eigen::Vector2d(2, 0.9);
    Circle ours, ipopts;
    const OptimizerResult a = minimize(ours, Eigen::Vector2d(-0.5, 0.5), s);
    s.options["mumps_mem_percent"] = "1000";
    const OptimizerResult b = minimize(ipopts, Eigen::Vector2d(-0.5, 0.5), s);
    EXPECT_EQ(a.reason, StopReason::GRADIENT_TOLERANCE) << a.message;
    EXPECT_NEAR(a.x.squaredNorm(), 1.5, 1e-6);
    EXPECT_GT(a.iterations, 5);
    EXPECT_EQ(a.iterations, b.iterations);
    ASSERT_EQ(ours.evaluated.size(), ipopts.evaluated.size());
    for (size_t k = 0; k < ours.evaluated.size(); ++k)
        EXPECT_EQ(ours.evaluated[k], ipopts.evaluated[k]) << "evaluation " << k;
    EXPECT_EQ(a.x, b.x);
    EXPECT_EQ(a.values.f, b.values.f);
}
