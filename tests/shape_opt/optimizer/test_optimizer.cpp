// minimize() behind one interface: settings validation, and the same analytic problems through
// every driver (Rosenbrock, constrained quadratics, a bound and a nonlinear constraint active
// together, the validity hook, random evaluation failures, stopping rules). The optima are
// computed here from the KKT conditions, independently of the optimizers.

#include "forward/common/error.hpp"
#include "shape_opt/optimizer/optimizer.hpp"

#include <Eigen/LU>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <ctime>
#include <functional>
#include <limits>
#include <stdexcept>

using namespace diffipc;

namespace {

constexpr double INF = std::numeric_limits<double>::infinity();

/// A problem that records what the optimizer did with it: evaluations, failures, the points
/// passed to iteration(); points may be declared invalid, the callback may stop the run.
class RecordingProblem : public OptimizationProblem {
public:
    /// Points where evaluate() fails (empty: none).
    std::function<bool(const VectorXd&)> invalid;
    /// max_valid_step() (empty: the default, 1).
    std::function<double(const VectorXd&, const VectorXd&)> valid_step;
    int stop_at = -1; ///< iteration() returns false from this iteration on (-1: never)
    int evaluations = 0, failures = 0;
    std::vector<VectorXd> iterates;
    std::vector<IterationInfo> infos;
    int invalid_iterates = 0; ///< points given to iteration() that are invalid (must stay 0)

    bool evaluate(const VectorXd& x, OptimizationValues& out) final
    {
        ++evaluations;
        if (invalid && invalid(x)) {
            ++failures;
            return false;
        }
        values(x, out);
        return true;
    }
    double max_valid_step(const VectorXd& x, const VectorXd& dx) final { return valid_step ? valid_step(x, dx) : 1.0; }
    bool iteration(const IterationInfo& info) final
    {
        iterates.push_back(*info.x);
        infos.push_back(info);
        if (invalid && invalid(*info.x))
            ++invalid_iterates;
        return stop_at < 0 || info.iteration < stop_at;
    }

protected:
    virtual void values(const VectorXd& x, OptimizationValues& out) const = 0;
};

/// Extended Rosenbrock (Moré, Garbow & Hillstrom 1981, problem 21): n/2 decoupled pairs
/// 100 (x_{2i+1} - x_{2i}^2)^2 + (1 - x_{2i})^2, minimum 0 at (1, ..., 1).
class Rosenbrock : public RecordingProblem {
public:
    explicit Rosenbrock(Index n)
        : m_n(n)
    {
    }
    Index size() const override { return m_n; }

protected:
    void values(const VectorXd& x, OptimizationValues& out) const override
    {
        out.f = 0;
        out.gradient = VectorXd::Zero(m_n);
        for (Index i = 0; i + 1 < m_n; i += 2) {
            const double a = x[i], b = x[i + 1], r = b - a * a;
            out.f += 100 * r * r + (1 - a) * (1 - a);
            out.gradient[i] = -400 * a * r - 2 * (1 - a);
            out.gradient[i + 1] = 200 * r;
        }
    }

private:
    Index m_n;
};

/// The standard start (-1.2, 1, -1.2, 1, ...).
VectorXd rosenbrock_start(Index n)
{
    VectorXd x(n);
    for (Index i = 0; i < n; ++i)
        x[i] = i % 2 == 0 ? -1.2 : 1.0;
    return x;
}

/// |x - a|^2 with a = (1, 2, 3) subject to x0 + x1 + x2 = 3 (an equality, or as the
/// inequality x0 + x1 + x2 <= 3) and x2 - x0 <= 1. Both are active at the optimum.
class LinearQuadratic : public RecordingProblem {
public:
    explicit LinearQuadratic(bool equality)
        : m_equality(equality)
    {
    }
    Index size() const override { return 3; }
    int inequalities() const override { return m_equality ? 1 : 2; }
    int equalities() const override { return m_equality ? 1 : 0; }

    static Eigen::Vector3d a() { return { 1, 2, 3 }; }
    /// Rows: the sum constraint, then x2 - x0 <= 1.
    static Eigen::Matrix<double, 2, 3> A()
    {
        Eigen::Matrix<double, 2, 3> A;
        A << 1, 1, 1, -1, 0, 1;
        return A;
    }
    static Eigen::Vector2d b() { return { 3, 1 }; }

protected:
    void values(const VectorXd& x, OptimizationValues& out) const override
    {
        out.f = (x - a()).squaredNorm();
        out.gradient = 2 * (x - a());
        const Eigen::Vector2d g = A() * x - b();
        if (m_equality) {
            out.equality = g.head<1>();
            out.equality_jacobian = A().topRows<1>();
            out.inequality = g.tail<1>();
            out.inequality_jacobian = A().bottomRows<1>();
        } else {
            out.inequality = g;
            out.inequality_jacobian = A();
        }
    }

private:
    bool m_equality;
};

/// (x0 - 2)^2 + (x1 - 2)^2 subject to x0^2 + x1^2 <= 2 and the bound x0 <= 0.5: the bound and
/// the circle are both active at the optimum (0.5, sqrt(1.75)).
class BoundAndCircle : public RecordingProblem {
public:
    Index size() const override { return 2; }
    int inequalities() const override { return 1; }

protected:
    void values(const VectorXd& x, OptimizationValues& out) const override
    {
        out.f = (x[0] - 2) * (x[0] - 2) + (x[1] - 2) * (x[1] - 2);
        out.gradient = Eigen::Vector2d(2 * (x[0] - 2), 2 * (x[1] - 2));
        out.inequality = VectorXd::Constant(1, x.squaredNorm() - 2);
        out.inequality_jacobian = 2 * x.transpose();
    }
};

/// (x0 - 2)^2 + (x1 - 1)^2 + 0.5 x0 x1, whose unconstrained minimum (28/15, 8/15) lies in
/// x0 > 1.5, declared invalid; max_valid_step() (when installed) cuts steps at x0 = 1.5.
class ValidityRegion : public RecordingProblem {
public:
    static constexpr double LIMIT = 1.5;
    explicit ValidityRegion(bool with_valid_step)
    {
        invalid = [](const VectorXd& x) { return x[0] > LIMIT; };
        if (with_valid_step)
            valid_step = [](const VectorXd& x, const VectorXd& dx) {
                if (dx[0] <= 0 || x[0] + dx[0] <= LIMIT)
                    return 1.0;
                return std::max(0.0, (LIMIT - x[0]) / dx[0]);
            };
    }
    Index size() const override { return 2; }

protected:
    void values(const VectorXd& x, OptimizationValues& out) const override
    {
        out.f = (x[0] - 2) * (x[0] - 2) + (x[1] - 1) * (x[1] - 1) + 0.5 * x[0] * x[1];
        out.gradient = Eigen::Vector2d(2 * (x[0] - 2) + 0.5 * x[1], 2 * (x[1] - 1) + 0.5 * x[0]);
    }
};

/// A deterministic pseudo-random number in [0, 1) from the bits of x (FNV-1a, then a mix),
/// so that a point fails or not whenever it is evaluated.
double hash_uniform(const VectorXd& x)
{
    std::uint64_t h = 1469598103934665603ull;
    for (Index i = 0; i < x.size(); ++i) {
        std::uint64_t bits;
        std::memcpy(&bits, &x[i], sizeof bits);
        h = (h ^ bits) * 1099511628211ull;
    }
    h ^= h >> 33;
    h *= 0xff51afd7ed558ccdull;
    h ^= h >> 33;
    return double(h >> 11) * 0x1.0p-53;
}

/// Settings for a tight convergence test.
OptimizerSettings tight(OptimizerAlgorithm algorithm)
{
    OptimizerSettings s;
    s.algorithm = algorithm;
    s.gradient_tolerance = 1e-10;
    s.relative_gradient_tolerance = 0;
    s.max_iterations = 20000;
    return s;
}

bool is_nlopt(OptimizerAlgorithm a)
{
    return a == OptimizerAlgorithm::MMA || a == OptimizerAlgorithm::CCSAQ || a == OptimizerAlgorithm::SLSQP;
}

std::string name_of(const ::testing::TestParamInfo<OptimizerAlgorithm>& info) { return to_string(info.param); }

/// Checks that every iterate was valid and the result's values belong to its x.
template <typename Problem> void expect_consistent(Problem& problem, const OptimizerResult& r)
{
    EXPECT_EQ(problem.invalid_iterates, 0);
    EXPECT_EQ(r.rejected, problem.failures);
    EXPECT_EQ(r.evaluations, problem.evaluations);
    ASSERT_EQ(r.x.size(), problem.size());
    EXPECT_TRUE(r.x.allFinite());
    EXPECT_TRUE(std::isfinite(r.values.f));
    OptimizationValues check;
    ASSERT_TRUE(problem.evaluate(r.x, check)) << "the result is not a valid point";
    EXPECT_EQ(check.f, r.values.f);
    EXPECT_GE(r.evaluation_seconds, 0);
    EXPECT_GE(r.optimizer_seconds, 0);
    EXPECT_GE(r.optimizer_cpu_seconds, 0);
}

double thread_cpu_seconds()
{
    timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

/// Keeps the calling thread busy for `seconds` of its CPU time (however loaded the machine is).
void burn_cpu(double seconds)
{
    const double end = thread_cpu_seconds() + seconds;
    volatile double sink = 0;
    while (thread_cpu_seconds() < end)
        for (int i = 0; i < 1000; ++i)
            sink = sink + 1e-9 * i;
}

} // namespace

// ---------------------------------------------------------------------------------------------
// Names and settings validation

TEST(Optimizer, AlgorithmNamesRoundTrip)
{
    for (auto a : { OptimizerAlgorithm::LBFGS, OptimizerAlgorithm::LBFGSB, OptimizerAlgorithm::IPOPT,
             OptimizerAlgorithm::MMA, OptimizerAlgorithm::CCSAQ, OptimizerAlgorithm::SLSQP })
        EXPECT_EQ(parse_optimizer_algorithm(to_string(a), "optimizer.algorithm"), a);
    EXPECT_EQ(parse_optimizer_algorithm("SLSQP", "f"), OptimizerAlgorithm::SLSQP);
    try {
        parse_optimizer_algorithm("bfgs", "optimizer.algorithm");
        FAIL();
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), "optimizer.algorithm");
        EXPECT_NE(std::string(e.what()).find("\"lbfgsb\""), std::string::npos) << e.what();
    }
    EXPECT_EQ(to_string(StopReason::ITERATION_BUDGET), "iteration_budget");
    EXPECT_EQ(to_string(StopReason::INVALID_START), "invalid_start");
}

namespace {
/// The field of the InputError minimize() throws, or "" when it does not throw one.
std::string error_field(OptimizationProblem& problem, const VectorXd& x0, const OptimizerSettings& s)
{
    try {
        minimize(problem, x0, s);
    } catch (const InputError& e) {
        return e.field();
    }
    return "";
}
} // namespace

TEST(Optimizer, RefusesBadBoundsAndStart)
{
    Rosenbrock p(2);
    const VectorXd x0 = rosenbrock_start(2);
    OptimizerSettings s;
    s.lower = VectorXd::Zero(3);
    EXPECT_EQ(error_field(p, x0, s), "optimizer.lower");
    s.lower = VectorXd();
    s.upper = VectorXd::Constant(1, 1.0);
    EXPECT_EQ(error_field(p, x0, s), "optimizer.upper");
    s.upper = VectorXd();
    s.lower = Eigen::Vector2d(-2, 3);
    s.upper = Eigen::Vector2d(2, 2); // lower[1] > upper[1]
    EXPECT_EQ(error_field(p, x0, s), "optimizer.lower");
    s.lower = Eigen::Vector2d(std::nan(""), -INF);
    s.upper = VectorXd();
    EXPECT_EQ(error_field(p, x0, s), "optimizer.lower");
    s.lower = VectorXd();
    EXPECT_EQ(error_field(p, Eigen::Vector2d(std::nan(""), 0), s), "optimizer.x0");
    EXPECT_EQ(error_field(p, Eigen::Vector2d(INF, 0), s), "optimizer.x0");
    EXPECT_EQ(error_field(p, VectorXd::Zero(3), s), "optimizer.x0");
    s.lower = Eigen::Vector2d(-1, -INF); // x0[0] = -1.2 is below it
    try {
        minimize(p, x0, s);
        FAIL();
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), "optimizer.x0");
        EXPECT_NE(std::string(e.what()).find("x0[0] = -1.2 is outside its bounds [-1, inf]"), std::string::npos)
            << e.what();
    }
    EXPECT_EQ(p.evaluations, 0); // refused before any evaluation
}

TEST(Optimizer, RefusesBadSettings)
{
    Rosenbrock p(2);
    const VectorXd x0 = rosenbrock_start(2);
    OptimizerSettings s;
    s.gradient_tolerance = -1;
    EXPECT_EQ(error_field(p, x0, s), "optimizer.gradient_tolerance");
    s = OptimizerSettings();
    s.f_tolerance = std::nan("");
    EXPECT_EQ(error_field(p, x0, s), "optimizer.f_tolerance");
    s = OptimizerSettings();
    s.lbfgs_memory = 0;
    EXPECT_EQ(error_field(p, x0, s), "optimizer.lbfgs_memory");
    s = OptimizerSettings();
    s.max_seconds = INF;
    EXPECT_EQ(error_field(p, x0, s), "optimizer.max_seconds");
    s = OptimizerSettings();
    s.algorithm = OptimizerAlgorithm::LBFGS;
    s.upper = Eigen::Vector2d(INF, 5);
    EXPECT_EQ(error_field(p, x0, s), "optimizer.algorithm");
    s.upper = Eigen::Vector2d(INF, INF); // infinite bounds are no bounds
    s.max_iterations = 1;
    EXPECT_EQ(error_field(p, x0, s), "");
    s = OptimizerSettings();
    s.options["m"] = "5";
    EXPECT_EQ(error_field(p, x0, s), "optimizer.options.m");
}

TEST(Optimizer, RefusesConstraintsForLbfgs)
{
    LinearQuadratic p(true);
    for (auto a : { OptimizerAlgorithm::LBFGS, OptimizerAlgorithm::LBFGSB }) {
        OptimizerSettings s;
        s.algorithm = a;
        try {
            minimize(p, VectorXd::Zero(3), s);
            FAIL();
        } catch (const InputError& e) {
            EXPECT_EQ(e.field(), "optimizer.algorithm");
            const std::string what = e.what();
            EXPECT_NE(what.find("use ipopt, mma, ccsaq or slsqp, or a penalty"), std::string::npos) << what;
        }
    }
}

TEST(Optimizer, RefusesEqualitiesForCcsa)
{
    LinearQuadratic p(true);
    for (auto a : { OptimizerAlgorithm::MMA, OptimizerAlgorithm::CCSAQ }) {
        OptimizerSettings s;
        s.algorithm = a;
        EXPECT_EQ(error_field(p, VectorXd::Zero(3), s), "optimizer.algorithm");
    }
    LinearQuadratic inequalities_only(false);
    OptimizerSettings s;
    s.algorithm = OptimizerAlgorithm::MMA;
    s.max_iterations = 2;
    EXPECT_EQ(error_field(inequalities_only, VectorXd::Zero(3), s), "");
}

TEST(Optimizer, WrongSizesFromTheProblemAreInputErrors)
{
    class WrongGradient : public OptimizationProblem {
    public:
        Index size() const override { return 2; }
        bool evaluate(const VectorXd&, OptimizationValues& out) override
        {
            out.f = 0;
            out.gradient = VectorXd::Zero(3);
            return true;
        }
    } p;
    EXPECT_EQ(error_field(p, VectorXd::Zero(2), OptimizerSettings()), "optimizer.problem");
}

// ---------------------------------------------------------------------------------------------
// Every driver on the same problems

class EveryOptimizer : public ::testing::TestWithParam<OptimizerAlgorithm> { };
INSTANTIATE_TEST_SUITE_P(Optimizer, EveryOptimizer,
    ::testing::Values(OptimizerAlgorithm::LBFGS, OptimizerAlgorithm::LBFGSB, OptimizerAlgorithm::IPOPT,
        OptimizerAlgorithm::MMA, OptimizerAlgorithm::CCSAQ, OptimizerAlgorithm::SLSQP),
    name_of);

class BoundedOptimizer : public ::testing::TestWithParam<OptimizerAlgorithm> { };
INSTANTIATE_TEST_SUITE_P(Optimizer, BoundedOptimizer,
    ::testing::Values(OptimizerAlgorithm::LBFGSB, OptimizerAlgorithm::IPOPT, OptimizerAlgorithm::MMA,
        OptimizerAlgorithm::CCSAQ, OptimizerAlgorithm::SLSQP),
    name_of);

class ConstrainedOptimizer : public ::testing::TestWithParam<OptimizerAlgorithm> { };
INSTANTIATE_TEST_SUITE_P(Optimizer, ConstrainedOptimizer,
    ::testing::Values(
        OptimizerAlgorithm::IPOPT, OptimizerAlgorithm::MMA, OptimizerAlgorithm::CCSAQ, OptimizerAlgorithm::SLSQP),
    name_of);

// Rosenbrock to 1e-6 in x (inf-norm) with gradient_tolerance 1e-10: near the minimum the
// Hessian's smallest eigenvalue is about 0.4, so the stop is ~1e-9 from it.
TEST_P(EveryOptimizer, Rosenbrock2D)
{
    Rosenbrock p(2);
    const OptimizerResult r = minimize(p, rosenbrock_start(2), tight(GetParam()));
    EXPECT_LT((r.x - VectorXd::Ones(2)).lpNorm<Eigen::Infinity>(), 1e-6) << r.message << "\n" << r.x.transpose();
    EXPECT_NE(r.reason, StopReason::FAILED) << r.message;
    expect_consistent(p, r);
    ASSERT_FALSE(p.infos.empty());
    EXPECT_EQ(p.infos.front().iteration, 0);
    EXPECT_EQ(p.iterates.front(), rosenbrock_start(2));
}

TEST_P(EveryOptimizer, Rosenbrock10D)
{
    Rosenbrock p(10);
    const OptimizerResult r = minimize(p, rosenbrock_start(10), tight(GetParam()));
    EXPECT_LT((r.x - VectorXd::Ones(10)).lpNorm<Eigen::Infinity>(), 1e-6) << r.message << "\n" << r.x.transpose();
    expect_consistent(p, r);
}

// x_{2i} <= 0.5 holds each pair at (0.5, 0.25): d f / d x_{2i} = -2 (1 - 0.5) = -1 pushes out
// of the box (the bound is active, its multiplier 1), d f / d x_{2i+1} = 0. 1e-6 in x.
TEST_P(BoundedOptimizer, RosenbrockWithActiveBound)
{
    for (Index n : { 2, 10 }) {
        Rosenbrock p(n);
        OptimizerSettings s = tight(GetParam());
        s.upper = VectorXd::Constant(n, INF);
        s.lower = VectorXd::Constant(n, -5.0);
        VectorXd expected(n);
        for (Index i = 0; i < n; i += 2) {
            s.upper[i] = 0.5;
            expected[i] = 0.5;
            expected[i + 1] = 0.25;
        }
        const OptimizerResult r = minimize(p, rosenbrock_start(n), s);
        EXPECT_LT((r.x - expected).lpNorm<Eigen::Infinity>(), 1e-6) << "n = " << n << ": " << r.message << "\n"
                                                                    << r.x.transpose();
        for (const VectorXd& x : p.iterates)
            EXPECT_TRUE((x.array() <= s.upper.array()).all() && (x.array() >= s.lower.array()).all());
        expect_consistent(p, r);
    }
}

// Both constraints active: x* = a - A^T (A A^T)^{-1} (A a - b), multipliers
// 2 (A A^T)^{-1} (A a - b) = (2, 1), positive, so the inequality form has the same optimum.
// 1e-6 in x; constraint_tolerance 1e-9 (the best feasible point within it is returned, which
// may lie up to that far outside). The box [-5, 5] is inactive; MMA and CCSAQ need finite
// bounds for their asymptotes (with infinite ones MMA stalls about 1e-6 away).
TEST_P(ConstrainedOptimizer, LinearEqualityAndInequality)
{
    const OptimizerAlgorithm a = GetParam();
    const auto A = LinearQuadratic::A();
    const Eigen::Matrix2d AAt = A * A.transpose();
    const Eigen::Vector2d multipliers = 2 * AAt.inverse() * (A * LinearQuadratic::a() - LinearQuadratic::b());
    ASSERT_GT(multipliers.minCoeff(), 0);
    const Eigen::Vector3d expected = LinearQuadratic::a() - A.transpose() * multipliers / 2;
    for (bool equality : { true, false }) {
        if (equality && (a == OptimizerAlgorithm::MMA || a == OptimizerAlgorithm::CCSAQ))
            continue; // refused (RefusesEqualitiesForCcsa)
        LinearQuadratic p(equality);
        OptimizerSettings s = tight(a);
        s.constraint_tolerance = 1e-9;
        s.lower = VectorXd::Constant(3, -5);
        s.upper = VectorXd::Constant(3, 5);
        if (is_nlopt(a))
            s.x_tolerance = 1e-12; // NLopt's own stop; the gradient rules skip constrained problems
        const OptimizerResult r = minimize(p, VectorXd::Zero(3), s);
        EXPECT_LT((r.x - expected).lpNorm<Eigen::Infinity>(), 1e-6)
            << (equality ? "equality: " : "inequalities: ") << r.message << "\n"
            << r.x.transpose();
        EXPECT_LE(r.max_violation, 1e-9);
        expect_consistent(p, r);
    }
}

// KKT at x* = (0.5, sqrt(1.75)): grad f + l grad c + m e0 = 0 with l = -grad f_1 / grad c_1 and
// m = -grad f_0 - l grad c_0, both positive (checked here). 1e-6 in x.
TEST_P(ConstrainedOptimizer, BoundAndNonlinearInequalityActive)
{
    const Eigen::Vector2d expected(0.5, std::sqrt(1.75));
    const Eigen::Vector2d grad_f = 2 * (expected - Eigen::Vector2d(2, 2));
    const Eigen::Vector2d grad_c = 2 * expected;
    const double l = -grad_f[1] / grad_c[1];
    const double m = -grad_f[0] - l * grad_c[0];
    ASSERT_GT(l, 0);
    ASSERT_GT(m, 0);

    BoundAndCircle p;
    OptimizerSettings s = tight(GetParam());
    s.lower = Eigen::Vector2d(-5, -5);
    s.upper = Eigen::Vector2d(0.5, 5);
    s.constraint_tolerance = 1e-9;
    if (is_nlopt(GetParam()))
        s.x_tolerance = 1e-12;
    // Not from (0, 0), where grad c = 0 (SLSQP's subproblem fails there: NLOPT_ROUNDOFF_LIMITED).
    const OptimizerResult r = minimize(p, Eigen::Vector2d(0.25, 0.5), s);
    EXPECT_LT((r.x - expected).lpNorm<Eigen::Infinity>(), 1e-6) << r.message << "\n" << r.x.transpose();
    EXPECT_LE(r.max_violation, 1e-9);
    expect_consistent(p, r);
}

// The unconstrained minimum lies in the invalid region x0 > 1.5. Every iterate must be valid,
// every failed evaluation counted, and the run must end at a valid point within 1e-3 of the
// boundary x0 = 1.5, below the start's f, with finite values. (Where along the boundary it
// ends is not specified: the optimizers do not know the boundary as a constraint, and stop
// when they cannot step across it.)
TEST_P(EveryOptimizer, ValidityRegion)
{
    for (bool with_valid_step : { true, false }) {
        ValidityRegion p(with_valid_step);
        OptimizerSettings s = tight(GetParam());
        s.max_iterations = 500;
        s.x_tolerance = 1e-12;
        const OptimizerResult r = minimize(p, Eigen::Vector2d(0, 0), s);
        SCOPED_TRACE(with_valid_step ? "with max_valid_step" : "without max_valid_step");
        EXPECT_LE(r.x[0], ValidityRegion::LIMIT);
        EXPECT_GT(r.x[0], ValidityRegion::LIMIT - 1e-3) << r.message << "\n" << r.x.transpose();
        EXPECT_LT(r.values.f, 5.0); // f(0, 0) = 5
        EXPECT_NE(r.reason, StopReason::FAILED) << r.message;
        expect_consistent(p, r);
        if (!with_valid_step || GetParam() == OptimizerAlgorithm::IPOPT || is_nlopt(GetParam()))
            EXPECT_GT(r.rejected, 0); // only L-BFGS uses max_valid_step
    }
}

// Evaluations fail at 20% of the points (a hash of x decides, so a point fails whenever it is
// asked for), never at the start: the run must still reach 1e-6 of the minimum.
TEST_P(EveryOptimizer, RandomEvaluationFailures)
{
    Rosenbrock p(2);
    const VectorXd x0 = rosenbrock_start(2);
    p.invalid = [x0](const VectorXd& x) { return x != x0 && hash_uniform(x) < 0.2; };
    const OptimizerResult r = minimize(p, x0, tight(GetParam()));
    EXPECT_LT((r.x - VectorXd::Ones(2)).lpNorm<Eigen::Infinity>(), 1e-6) << r.message << "\n" << r.x.transpose();
    EXPECT_GT(r.rejected, 0);
    expect_consistent(p, r);
}

TEST_P(EveryOptimizer, InvalidStartIsAResult)
{
    Rosenbrock p(2);
    p.invalid = [](const VectorXd&) { return true; };
    OptimizerResult r;
    ASSERT_NO_THROW(r = minimize(p, rosenbrock_start(2), OptimizerSettings { GetParam() }));
    EXPECT_EQ(r.reason, StopReason::INVALID_START);
    EXPECT_EQ(r.evaluations, 1);
    EXPECT_EQ(r.rejected, 1);
    EXPECT_EQ(r.x, rosenbrock_start(2));
    EXPECT_TRUE(p.infos.empty());
}

// Reaching the iteration budget is a normal result with that many iterations.
TEST_P(EveryOptimizer, IterationBudget)
{
    Rosenbrock p(2);
    OptimizerSettings s = tight(GetParam());
    s.max_iterations = 5;
    const OptimizerResult r = minimize(p, rosenbrock_start(2), s);
    EXPECT_EQ(r.reason, StopReason::ITERATION_BUDGET) << r.message;
    EXPECT_EQ(r.iterations, 5);
    EXPECT_LT(r.values.f, 24.2); // f(x0) = 24.2
    expect_consistent(p, r);
}

// The optimizer's CPU time leaves out the CPU time of the evaluations and of the callback: each
// burns 5 ms of the thread's CPU time, 2D Rosenbrock's own costs far less.
TEST_P(EveryOptimizer, CpuTimeLeavesOutEvaluationsAndCallback)
{
    constexpr double BURN = 0.005;
    class Busy : public OptimizationProblem {
    public:
        Index size() const override { return 2; }
        bool evaluate(const VectorXd& x, OptimizationValues& out) override
        {
            burn_cpu(BURN);
            ++evaluations;
            const double a = x[0], b = x[1], r = b - a * a;
            out.f = 100 * r * r + (1 - a) * (1 - a);
            out.gradient = Eigen::Vector2d(-400 * a * r - 2 * (1 - a), 200 * r);
            return true;
        }
        bool iteration(const IterationInfo& info) override
        {
            burn_cpu(BURN);
            cpu.push_back(info.optimizer_cpu_seconds);
            wall.push_back(info.optimizer_seconds);
            return true;
        }
        int evaluations = 0;
        std::vector<double> cpu, wall;
    } p;
    OptimizerSettings s = tight(GetParam());
    s.max_iterations = 5;
    const OptimizerResult r = minimize(p, rosenbrock_start(2), s);
    const double burnt = BURN * double(p.evaluations + int(p.cpu.size()));
    ASSERT_GE(burnt, 0.02);
    EXPECT_LT(r.optimizer_cpu_seconds, 0.5 * burnt) << r.message;
    EXPECT_GT(r.optimizer_cpu_seconds, 0);
    // CPU time of the optimizer's own stretches of the run cannot exceed their wall time.
    EXPECT_LE(r.optimizer_cpu_seconds, r.optimizer_seconds + 1e-3);
    for (size_t k = 0; k < p.cpu.size(); ++k) {
        EXPECT_LE(p.cpu[k], r.optimizer_cpu_seconds);
        EXPECT_LE(p.cpu[k], p.wall[k] + 1e-3);
        if (k > 0)
            EXPECT_GE(p.cpu[k], p.cpu[k - 1]);
    }
}

TEST_P(EveryOptimizer, UserStop)
{
    for (int stop_at : { 0, 3 }) {
        Rosenbrock p(2);
        p.stop_at = stop_at;
        const OptimizerResult r = minimize(p, rosenbrock_start(2), tight(GetParam()));
        EXPECT_EQ(r.reason, StopReason::USER_STOP) << r.message;
        EXPECT_EQ(r.iterations, stop_at);
        ASSERT_FALSE(p.infos.empty());
        EXPECT_EQ(p.infos.back().iteration, stop_at);
        for (size_t k = 1; k < p.infos.size(); ++k) {
            EXPECT_GE(p.infos[k].evaluations, p.infos[k - 1].evaluations);
            EXPECT_GE(p.infos[k].evaluation_seconds, p.infos[k - 1].evaluation_seconds);
        }
    }
}

TEST_P(EveryOptimizer, ExceptionsFromTheProblemPassThrough)
{
    class Throwing : public Rosenbrock {
    public:
        Throwing()
            : Rosenbrock(2)
        {
            invalid = [this](const VectorXd&) {
                if (++m_calls == 6)
                    throw std::runtime_error("forward solve crashed");
                return false;
            };
        }

    private:
        int m_calls = 0;
    } p;
    EXPECT_THROW(
        {
            try {
                minimize(p, rosenbrock_start(2), tight(GetParam()));
            } catch (const std::runtime_error& e) {
                EXPECT_STREQ(e.what(), "forward solve crashed");
                throw;
            }
        },
        std::runtime_error);
}

// ---------------------------------------------------------------------------------------------
// The result is the optimizer's last iterate; the best point seen is reported beside it
// (issue 46: a run reported the best point of another branch of a discontinuous J as its result)

namespace {

/// f = x^2 (1 variable), or x^2 subject to x >= 0.5 (c = 0.5 - x <= 0).
class Parabola : public RecordingProblem {
public:
    explicit Parabola(bool constrained = false)
        : m_constrained(constrained)
    {
    }
    Index size() const override { return 1; }
    int inequalities() const override { return m_constrained ? 1 : 0; }

protected:
    void values(const VectorXd& x, OptimizationValues& out) const override
    {
        out.f = x[0] * x[0];
        out.gradient = VectorXd::Constant(1, 2 * x[0]);
        out.inequality = VectorXd::Constant(m_constrained ? 1 : 0, 0.5 - x[0]);
        out.inequality_jacobian = MatrixXd::Constant(m_constrained ? 1 : 0, 1, -1.0);
    }

private:
    bool m_constrained;
};

/// f = 0.005 (x - 2)^2, less 1 for x > 1: a jump the gradient does not see.
class JumpingParabola : public RecordingProblem {
public:
    Index size() const override { return 1; }

protected:
    void values(const VectorXd& x, OptimizationValues& out) const override
    {
        out.f = 0.005 * (x[0] - 2) * (x[0] - 2) - (x[0] > 1 ? 1.0 : 0.0);
        out.gradient = VectorXd::Constant(1, 0.01 * (x[0] - 2));
    }
};

} // namespace

TEST(OptimizerResult, IsTheLastIterateWithTheBestPointSeenBesideIt)
{
    Parabola p;
    OptimizerSettings s;
    optimizer_detail::Run run(p, s);
    const VectorXd x0 = VectorXd::Constant(1, 1.0), trial = VectorXd::Constant(1, 0.0), x1 = VectorXd::Constant(1, 0.5);
    OptimizationValues v0, vt, v1;
    ASSERT_TRUE(run.evaluate(x0, v0));
    run.iteration(0, x0, v0, 2, 0);
    ASSERT_TRUE(run.evaluate(trial, vt)); // the lowest f seen, never accepted
    ASSERT_TRUE(run.evaluate(x1, v1));
    run.iteration(1, x1, v1, 1, 0.5);
    const OptimizerResult r = run.finish(StopReason::GRADIENT_TOLERANCE, "converged", 1);
    EXPECT_EQ(r.reason, StopReason::GRADIENT_TOLERANCE);
    EXPECT_EQ(r.x, x1);
    EXPECT_EQ(r.values.f, 0.25);
    ASSERT_TRUE(r.has_best);
    EXPECT_EQ(r.best_x, trial);
    EXPECT_EQ(r.best_values.f, 0);
    EXPECT_EQ(r.best_evaluation, 2);
    EXPECT_EQ(r.best_iteration, -1);
}

TEST(OptimizerResult, BestPointThatWasAcceptedKnowsItsIteration)
{
    Parabola p;
    OptimizerSettings s;
    optimizer_detail::Run run(p, s);
    const VectorXd x0 = VectorXd::Constant(1, 0.1), x1 = VectorXd::Constant(1, 0.3);
    OptimizationValues v0, v1;
    ASSERT_TRUE(run.evaluate(x0, v0));
    run.iteration(0, x0, v0, 0.2, 0);
    ASSERT_TRUE(run.evaluate(x1, v1));
    run.iteration(1, x1, v1, 0.6, 0.2); // a non-monotone optimizer's step up
    const OptimizerResult r = run.finish(StopReason::ITERATION_BUDGET, "budget", 1);
    EXPECT_EQ(r.x, x1);
    EXPECT_EQ(r.best_x, x0);
    EXPECT_EQ(r.best_iteration, 0);
    EXPECT_EQ(r.best_evaluation, 1);
}

// A tolerance stop at a last iterate outside the constraints is not convergence, even when a
// feasible point was seen earlier (that point is the best point, not the result).
TEST(OptimizerResult, ToleranceStopAtAnInfeasibleLastIterateIsInfeasible)
{
    Parabola p(true);
    OptimizerSettings s;
    s.algorithm = OptimizerAlgorithm::IPOPT;
    optimizer_detail::Run run(p, s);
    const VectorXd x0 = VectorXd::Constant(1, 1.0), x1 = VectorXd::Constant(1, 0.2);
    OptimizationValues v0, v1;
    ASSERT_TRUE(run.evaluate(x0, v0));
    run.iteration(0, x0, v0, 2, 0);
    ASSERT_TRUE(run.evaluate(x1, v1));
    run.iteration(1, x1, v1, 0.4, 0.8);
    const OptimizerResult r = run.finish(StopReason::X_TOLERANCE, "small step", 1);
    EXPECT_EQ(r.reason, StopReason::INFEASIBLE) << r.message;
    EXPECT_EQ(r.x, x1);
    EXPECT_NEAR(r.max_violation, 0.3, 1e-15);
    EXPECT_EQ(r.best_x, x0);
    EXPECT_EQ(r.best_max_violation, 0);
}

// Every driver crosses the jump at x = 1 on its way to x = 2 and records the step: J fell by
// about 1 where the gradients at the step's ends predict a change of order 0.01.
TEST_P(BoundedOptimizer, JumpOfTheObjectiveIsRecorded)
{
    JumpingParabola p;
    OptimizerSettings s = tight(GetParam());
    s.lower = VectorXd::Constant(1, -5);
    s.upper = VectorXd::Constant(1, 5);
    s.x_tolerance = 1e-10; // NLopt's stop
    const OptimizerResult r = minimize(p, VectorXd::Constant(1, 0.3), s);
    EXPECT_NEAR(r.x[0], 2, 1e-4) << r.message;
    ASSERT_FALSE(r.jumps.empty()) << r.message;
    const StepJump& j = r.jumps.front();
    EXPECT_LT(j.change, -0.9);
    EXPECT_LT(std::abs(j.predicted), 0.05);
    EXPECT_GE(r.steps_checked, 1);
    // The first iterate past x = 1 is the step's end.
    int crossing = -1;
    for (size_t k = 0; k < p.iterates.size() && crossing < 0; ++k)
        if (p.iterates[k][0] > 1)
            crossing = p.infos[k].iteration;
    EXPECT_EQ(j.iteration, crossing);
}

// No step of a smooth problem is taken for a jump, however curved (Rosenbrock's valley, a
// constrained quadratic): the check must not cry wolf.
TEST_P(EveryOptimizer, SmoothProblemsHaveNoJumps)
{
    for (Index n : { 2, 10 }) {
        Rosenbrock p(n);
        const OptimizerResult r = minimize(p, rosenbrock_start(n), tight(GetParam()));
        EXPECT_GT(r.steps_checked, 5) << n;
        EXPECT_TRUE(r.jumps.empty()) << "n = " << n << ": step to iteration " << r.jumps.front().iteration
                                     << " changed f by " << r.jumps.front().change << ", predicted "
                                     << r.jumps.front().predicted << " (first-order scale "
                                     << r.jumps.front().first_order << ")";
        // Smooth and monotone or converged: the last iterate is the best point to round-off.
        ASSERT_TRUE(r.has_best);
        EXPECT_LE(r.values.f - r.best_values.f, 1e-12) << r.message;
    }
}
