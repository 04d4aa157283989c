// The projected L-BFGS of lbfgsb.cpp: what only it does (max_valid_step, skipped curvature
// pairs, its line search and stopping rules). The shared problems run in test_optimizer.cpp.

#include "forward/common/error.hpp"
#include "shape_opt/optimizer/optimizer.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <thread>

using namespace diffipc;

namespace {

constexpr double INF = std::numeric_limits<double>::infinity();

/// A problem from a lambda, recording the callback's view.
class LambdaProblem : public OptimizationProblem {
public:
    using Function = std::function<void(const VectorXd&, double&, VectorXd&)>;
    LambdaProblem(Index n, Function f)
        : m_n(n)
        , m_f(std::move(f))
    {
    }
    Index size() const override { return m_n; }
    bool evaluate(const VectorXd& x, OptimizationValues& out) override
    {
        ++evaluations;
        evaluated.push_back(x);
        if (invalid && invalid(x))
            return false;
        m_f(x, out.f, out.gradient);
        return true;
    }
    double max_valid_step(const VectorXd& x, const VectorXd& dx) override
    {
        return valid_step ? valid_step(x, dx) : 1.0;
    }
    bool iteration(const IterationInfo& info) override
    {
        infos.push_back(info); // info.values points into the optimizer: copy what is needed
        iterates.push_back(*info.x);
        fs.push_back(info.values->f);
        return true;
    }
    std::function<bool(const VectorXd&)> invalid;
    std::function<double(const VectorXd&, const VectorXd&)> valid_step;
    int evaluations = 0;
    std::vector<VectorXd> evaluated, iterates;
    std::vector<double> fs; ///< f at the iterates
    std::vector<IterationInfo> infos;

private:
    Index m_n;
    Function m_f;
};

/// sum (x_i^4 / 4 - x_i^2 / 2): concave for |x_i| < 1/sqrt(3), minima at x_i = +-1.
void double_well(const VectorXd& x, double& f, VectorXd& g)
{
    f = (x.array().pow(4) / 4 - x.array().square() / 2).sum();
    g = (x.array().cube() - x.array()).matrix();
}

/// Minima at +-2, f'' = 3 x^2 - 4 < 0 for |x| < 1.15: wider than the first (unit) step.
void wide_double_well(const VectorXd& x, double& f, VectorXd& g)
{
    f = (x.array().pow(4) / 4 - 2 * x.array().square()).sum();
    g = (x.array().cube() - 4 * x.array()).matrix();
}

void quadratic(const VectorXd& x, double& f, VectorXd& g)
{
    f = 0.5 * x.squaredNorm();
    g = x;
}

OptimizerSettings lbfgsb()
{
    OptimizerSettings s;
    s.algorithm = OptimizerAlgorithm::LBFGSB;
    s.gradient_tolerance = 1e-10;
    s.relative_gradient_tolerance = 0;
    return s;
}

} // namespace

TEST(Lbfgsb, RefusesConstraintsNamingTheAlternatives)
{
    class Constrained : public LambdaProblem {
    public:
        Constrained()
            : LambdaProblem(2, quadratic)
        {
        }
        int inequalities() const override { return 1; }
    } p;
    OptimizerSettings s = lbfgsb();
    try {
        minimize(p, VectorXd::Zero(2), s);
        FAIL();
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), "optimizer.algorithm");
        EXPECT_NE(std::string(e.what()).find("use ipopt, mma, ccsaq or slsqp, or a penalty"), std::string::npos);
    }
}

// The first step from x = 0.1 (a unit step, to 1.1) lies where f'' < 0: its pair has s.y < 0
// and is skipped; the run still reaches the minimum x = 2 to 1e-8 (gradient_tolerance 1e-10,
// f'' = 8 there).
TEST(Lbfgsb, SkipsPairsWithoutPositiveCurvature)
{
    LambdaProblem p(2, wide_double_well);
    const OptimizerResult r = minimize(p, VectorXd::Constant(2, 0.1), lbfgsb());
    EXPECT_EQ(r.reason, StopReason::GRADIENT_TOLERANCE) << r.message;
    EXPECT_LT((r.x - VectorXd::Constant(2, 2.0)).lpNorm<Eigen::Infinity>(), 1e-8) << r.x.transpose();
    ASSERT_GE(p.iterates.size(), 2u);
    const VectorXd s = p.iterates[1] - p.iterates[0];
    VectorXd g0, g1;
    double f;
    wide_double_well(p.iterates[0], f, g0);
    wide_double_well(p.iterates[1], f, g1);
    EXPECT_LT(s.dot(g1 - g0), 0); // the first pair indeed had negative curvature
}

// With an exact max_valid_step, no trial point is ever invalid: nothing is rejected, and every
// evaluated point is valid. The boundary is approached, never crossed.
TEST(Lbfgsb, MaxValidStepKeepsTrialsValid)
{
    LambdaProblem p(2, [](const VectorXd& x, double& f, VectorXd& g) {
        f = (x[0] - 3) * (x[0] - 3) + (x[1] - 1) * (x[1] - 1);
        g = Eigen::Vector2d(2 * (x[0] - 3), 2 * (x[1] - 1));
    });
    p.invalid = [](const VectorXd& x) { return x.squaredNorm() >= 4; }; // outside the disc of radius 2
    p.valid_step = [](const VectorXd& x, const VectorXd& dx) {
        // the smallest t > 0 with |x + t dx| = 2, if below 1 (x inside the disc)
        const double a = dx.squaredNorm(), b = 2 * x.dot(dx), c = x.squaredNorm() - 4;
        const double t = (-b + std::sqrt(b * b - 4 * a * c)) / (2 * a);
        return std::min(1.0, std::max(0.0, t));
    };
    OptimizerSettings s = lbfgsb();
    s.max_iterations = 200;
    const OptimizerResult r = minimize(p, Eigen::Vector2d(0, 0), s);
    EXPECT_EQ(r.rejected, 0) << r.message;
    for (const VectorXd& x : p.evaluated)
        EXPECT_LT(x.squaredNorm(), 4);
    EXPECT_GT(r.x.norm(), 2 - 1e-3) << r.message << " " << r.x.transpose();
    EXPECT_NE(r.reason, StopReason::FAILED);
}

// A gradient of the wrong sign: no trial decreases f, the line search gives up after its 40
// trials and once more from steepest descent, and the start (the best point) is returned.
TEST(Lbfgsb, StalledLineSearch)
{
    LambdaProblem p(2, [](const VectorXd& x, double& f, VectorXd& g) {
        f = x.squaredNorm();
        g = -2 * x;
    });
    const OptimizerResult r = minimize(p, Eigen::Vector2d(1, 1), lbfgsb());
    EXPECT_EQ(r.reason, StopReason::LINE_SEARCH_STALLED) << r.message;
    EXPECT_EQ(r.x, Eigen::Vector2d(1, 1));
    EXPECT_EQ(r.iterations, 0);
    EXPECT_LE(p.evaluations, 1 + 2 * 40);
}

// Every point but the start is invalid: the same stall, with every trial rejected.
TEST(Lbfgsb, EverythingButTheStartInvalid)
{
    LambdaProblem p(2, quadratic);
    p.invalid = [](const VectorXd& x) { return x != Eigen::Vector2d(1, 1); };
    const OptimizerResult r = minimize(p, Eigen::Vector2d(1, 1), lbfgsb());
    EXPECT_EQ(r.reason, StopReason::LINE_SEARCH_STALLED) << r.message;
    EXPECT_EQ(r.rejected, p.evaluations - 1);
    EXPECT_EQ(r.x, Eigen::Vector2d(1, 1));
}

TEST(Lbfgsb, XAndFTolerances)
{
    {
        LambdaProblem p(2, double_well);
        OptimizerSettings s = lbfgsb();
        s.x_tolerance = 1e-3;
        const OptimizerResult r = minimize(p, VectorXd::Constant(2, 0.1), s);
        EXPECT_EQ(r.reason, StopReason::X_TOLERANCE) << r.message;
        EXPECT_LE(p.infos.back().step_norm, 1e-3);
        EXPECT_GT(p.infos[p.infos.size() - 2].step_norm, 1e-3);
    }
    {
        LambdaProblem p(2, double_well);
        OptimizerSettings s = lbfgsb();
        s.f_tolerance = 1e-6;
        const OptimizerResult r = minimize(p, VectorXd::Constant(2, 0.1), s);
        EXPECT_EQ(r.reason, StopReason::F_TOLERANCE) << r.message;
        const size_t k = p.fs.size() - 1;
        EXPECT_LE(std::abs(p.fs[k] - p.fs[k - 1]), 1e-6 * std::max(std::abs(p.fs[k]), std::abs(p.fs[k - 1])));
    }
}

TEST(Lbfgsb, RelativeGradientTolerance)
{
    LambdaProblem p(2, double_well);
    OptimizerSettings s = lbfgsb();
    s.gradient_tolerance = 0;
    s.relative_gradient_tolerance = 1e-3;
    const OptimizerResult r = minimize(p, VectorXd::Constant(2, 0.1), s);
    EXPECT_EQ(r.reason, StopReason::GRADIENT_TOLERANCE) << r.message;
    EXPECT_LE(p.infos.back().gradient_norm, 1e-3 * p.infos.front().gradient_norm);
    EXPECT_GT(p.infos[p.infos.size() - 2].gradient_norm, 1e-3 * p.infos.front().gradient_norm);
}

TEST(Lbfgsb, StationaryStart)
{
    LambdaProblem p(2, quadratic);
    const OptimizerResult r = minimize(p, VectorXd::Zero(2), lbfgsb());
    EXPECT_EQ(r.reason, StopReason::GRADIENT_TOLERANCE);
    EXPECT_EQ(r.iterations, 0);
    EXPECT_EQ(r.evaluations, 1);
}

// A variable with lower == upper never moves; one whose bound is active has a zero entry in
// the projected gradient; the reported gradient_norm is the projected one.
TEST(Lbfgsb, FixedAndActiveVariables)
{
    LambdaProblem p(3, [](const VectorXd& x, double& f, VectorXd& g) {
        f = (x - Eigen::Vector3d(2, 2, 2)).squaredNorm();
        g = 2 * (x - Eigen::Vector3d(2, 2, 2));
    });
    OptimizerSettings s = lbfgsb();
    s.lower = Eigen::Vector3d(0.5, -INF, -INF);
    s.upper = Eigen::Vector3d(0.5, 1, INF);
    const OptimizerResult r = minimize(p, Eigen::Vector3d(0.5, 0, 0), s);
    EXPECT_EQ(r.reason, StopReason::GRADIENT_TOLERANCE) << r.message;
    for (const VectorXd& x : p.evaluated)
        EXPECT_EQ(x[0], 0.5);
    EXPECT_LT((r.x - Eigen::Vector3d(0.5, 1, 2)).lpNorm<Eigen::Infinity>(), 1e-10);
    EXPECT_LE(p.infos.back().gradient_norm, 1e-10); // the held entries (-3, -2) do not count
    EXPECT_EQ(r.max_violation, 0);
}

TEST(Lbfgsb, MemoryOfOnePairStillConverges)
{
    LambdaProblem p(2, [](const VectorXd& x, double& f, VectorXd& g) {
        const double a = x[0], b = x[1], r = b - a * a;
        f = 100 * r * r + (1 - a) * (1 - a);
        g = Eigen::Vector2d(-400 * a * r - 2 * (1 - a), 200 * r);
    });
    OptimizerSettings s = lbfgsb();
    s.lbfgs_memory = 1;
    s.max_iterations = 10000;
    const OptimizerResult r = minimize(p, Eigen::Vector2d(-1.2, 1), s);
    EXPECT_LT((r.x - Eigen::Vector2d(1, 1)).lpNorm<Eigen::Infinity>(), 1e-6) << r.message;
}

// The wall-time budget: each evaluation sleeps 5 ms, the budget is 30 ms; the split of the
// times puts the sleeping into evaluation_seconds.
TEST(Lbfgsb, TimeBudget)
{
    LambdaProblem p(2, [](const VectorXd& x, double& f, VectorXd& g) {
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
        double_well(x, f, g);
    });
    OptimizerSettings s = lbfgsb();
    s.max_seconds = 0.03;
    const OptimizerResult r = minimize(p, VectorXd::Constant(2, 0.1), s);
    EXPECT_EQ(r.reason, StopReason::TIME_BUDGET) << r.message;
    EXPECT_GT(r.evaluation_seconds, 0.02);
    EXPECT_LT(r.optimizer_seconds, r.evaluation_seconds);
}

TEST(Lbfgsb, IterationInfo)
{
    LambdaProblem p(2, double_well);
    const OptimizerResult r = minimize(p, VectorXd::Constant(2, 0.1), lbfgsb());
    ASSERT_EQ(int(p.infos.size()), r.iterations + 1);
    for (size_t k = 0; k < p.infos.size(); ++k) {
        EXPECT_EQ(p.infos[k].iteration, int(k));
        if (k > 0) {
            EXPECT_DOUBLE_EQ(p.infos[k].step_norm, (p.iterates[k] - p.iterates[k - 1]).lpNorm<Eigen::Infinity>());
            EXPECT_LE(p.fs[k], p.fs[k - 1]); // Armijo: monotone (equal at round-off)
        }
    }
}
