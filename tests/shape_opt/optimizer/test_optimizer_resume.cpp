// resume_minimize(): a run stopped after some iteration (by its callback or its budget) and
// continued from the checkpoint its callback was given. L-BFGS(-B) must repeat the uninterrupted
// run's iterates exactly (the problems here are deterministic, so bit for bit); Ipopt and NLopt
// restart from the last iterate and must still converge, with iteration numbers and counts
// going on.

#include "forward/common/error.hpp"
#include "shape_opt/optimizer/optimizer.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

using namespace diffipc;

namespace {

constexpr double INF = std::numeric_limits<double>::infinity();

/// Records the iterates and the last checkpoint; the callback stops from iteration stop_at on.
class Recording : public OptimizationProblem {
public:
    int stop_at = -1;
    int evaluations = 0;
    std::vector<int> iterations;
    std::vector<VectorXd> iterates;
    std::vector<double> values;
    OptimizerCheckpoint last;

    bool iteration(const IterationInfo& info) override
    {
        iterations.push_back(info.iteration);
        iterates.push_back(*info.x);
        values.push_back(info.values->f);
        EXPECT_NE(info.checkpoint, nullptr);
        if (info.checkpoint)
            last = *info.checkpoint; // a copy, as a file would keep it
        return stop_at < 0 || info.iteration < stop_at;
    }
};

/// Extended Rosenbrock with n/2 pairs, the first variable of each pair bounded above by 0.9
/// (active at the bounded optimum), so that the active set and the two-metric step take part.
class BoundedRosenbrock : public Recording {
public:
    explicit BoundedRosenbrock(Index n)
        : m_n(n)
    {
    }
    Index size() const override { return m_n; }
    bool evaluate(const VectorXd& x, OptimizationValues& out) override
    {
        ++evaluations;
        out.f = 0;
        out.gradient = VectorXd::Zero(m_n);
        for (Index i = 0; i + 1 < m_n; i += 2) {
            const double a = x[i], b = x[i + 1], r = b - a * a;
            out.f += 100 * r * r + (1 - a) * (1 - a);
            out.gradient[i] = -400 * a * r - 2 * (1 - a);
            out.gradient[i + 1] = 200 * r;
        }
        return true;
    }
    OptimizerSettings settings() const
    {
        OptimizerSettings s;
        s.algorithm = OptimizerAlgorithm::LBFGSB;
        s.lower = VectorXd::Constant(m_n, -INF);
        s.upper = VectorXd::Constant(m_n, INF);
        for (Index i = 0; i < m_n; i += 2)
            s.upper[i] = 0.9;
        s.gradient_tolerance = 1e-10;
        s.relative_gradient_tolerance = 0;
        s.lbfgs_memory = 4; // fewer pairs than iterations: the memory's window slides
        s.max_iterations = 200;
        return s;
    }
    VectorXd start() const
    {
        VectorXd x(m_n);
        for (Index i = 0; i < m_n; ++i)
            x[i] = i % 2 == 0 ? -1.2 : 1.0;
        return x;
    }

private:
    Index m_n;
};

/// min |x - (1, 2, 3)|^2 subject to x0 + x1 + x2 <= 3 and x2 - x0 <= 1, 0 <= x <= 5;
/// optimum (1/2, 1, 3/2): x = a - (2 (1, 1, 1) + 1 (-1, 0, 1)) / 2, both constraints active with
/// the KKT multipliers 2 and 1.
class ConstrainedQuadratic : public Recording {
public:
    Index size() const override { return 3; }
    int inequalities() const override { return 2; }
    bool evaluate(const VectorXd& x, OptimizationValues& out) override
    {
        ++evaluations;
        const Eigen::Vector3d a(1, 2, 3);
        out.f = (x - a).squaredNorm();
        out.gradient = 2 * (x - a);
        Eigen::Matrix<double, 2, 3> A;
        A << 1, 1, 1, -1, 0, 1;
        out.inequality = A * x - Eigen::Vector2d(3, 1);
        out.inequality_jacobian = A;
        return true;
    }
    static Eigen::Vector3d optimum() { return { 0.5, 1.0, 1.5 }; }
};

/// The first run stopped at `stop_at` by its callback, then resumed with `settings`.
template <typename Problem>
void stop_and_resume(Problem& first, Problem& second, const VectorXd& x0, const OptimizerSettings& settings,
    int stop_at, OptimizerResult& stopped, OptimizerResult& resumed)
{
    first.stop_at = stop_at;
    stopped = minimize(first, x0, settings);
    ASSERT_EQ(stopped.reason, StopReason::USER_STOP) << stopped.message;
    ASSERT_EQ(first.last.iteration, stop_at);
    resumed = resume_minimize(second, first.last, settings);
}

TEST(OptimizerResume, LbfgsbRepeatsTheUninterruptedIteratesBitForBit)
{
    BoundedRosenbrock whole(6);
    const OptimizerResult reference = minimize(whole, whole.start(), whole.settings());
    ASSERT_EQ(reference.reason, StopReason::GRADIENT_TOLERANCE) << reference.message;
    ASSERT_GT(reference.iterations, 20); // enough iterations for the memory (4 pairs) to slide
    EXPECT_NEAR(reference.x[0], 0.9, 1e-12); // the bound is active at the optimum

    for (int stop_at : { 0, 1, 7, 15 }) {
        SCOPED_TRACE("stopped at iteration " + std::to_string(stop_at));
        BoundedRosenbrock first(6), second(6);
        OptimizerResult stopped, resumed;
        stop_and_resume(first, second, whole.start(), whole.settings(), stop_at, stopped, resumed);
        if (stop_at > 0)
            EXPECT_FALSE(first.last.lbfgs_pairs.empty());
        // The resumed run reports the iterations after the checkpoint's, each exactly as the
        // uninterrupted run did.
        ASSERT_EQ(second.iterates.size() + size_t(stop_at) + 1, whole.iterates.size());
        for (size_t i = 0; i < second.iterates.size(); ++i) {
            const size_t k = size_t(stop_at) + 1 + i;
            EXPECT_EQ(second.iterations[i], whole.iterations[k]);
            EXPECT_TRUE(second.iterates[i] == whole.iterates[k]) << "iteration " << k;
            EXPECT_EQ(second.values[i], whole.values[k]) << "iteration " << k;
        }
        EXPECT_EQ(resumed.reason, reference.reason);
        EXPECT_EQ(resumed.iterations, reference.iterations);
        // The counts describe the whole run: the first part's evaluations and the second's.
        EXPECT_EQ(resumed.evaluations, reference.evaluations);
        EXPECT_EQ(first.evaluations + second.evaluations, whole.evaluations);
        EXPECT_TRUE(resumed.x == reference.x);
        EXPECT_EQ(resumed.values.f, reference.values.f);
    }
}

TEST(OptimizerResume, LbfgsbAfterItsIterationBudgetWithALargerBudget)
{
    BoundedRosenbrock whole(6);
    const OptimizerResult reference = minimize(whole, whole.start(), whole.settings());
    BoundedRosenbrock first(6), second(6);
    OptimizerSettings small = whole.settings();
    small.max_iterations = 9;
    const OptimizerResult stopped = minimize(first, first.start(), small);
    ASSERT_EQ(stopped.reason, StopReason::ITERATION_BUDGET);
    ASSERT_EQ(first.last.iteration, 9);
    // With the same budget there is nothing left to do; no evaluation is made.
    {
        BoundedRosenbrock again(6);
        const OptimizerResult r = resume_minimize(again, first.last, small);
        EXPECT_EQ(r.reason, StopReason::ITERATION_BUDGET);
        EXPECT_EQ(r.iterations, 9);
        EXPECT_EQ(again.evaluations, 0);
        EXPECT_TRUE(r.x == first.last.x);
    }
    const OptimizerResult resumed = resume_minimize(second, first.last, whole.settings());
    EXPECT_EQ(resumed.iterations, reference.iterations);
    EXPECT_TRUE(resumed.x == reference.x);
    EXPECT_EQ(resumed.evaluations, reference.evaluations);
}

TEST(OptimizerResume, LbfgsbStoppedAtItsLastIterationEndsWithTheToleranceAtOnce)
{
    // The uninterrupted run converges at iteration K; a run whose callback stops it at K did
    // not make the checks that follow the callback: its resume makes them and ends there.
    BoundedRosenbrock whole(6);
    const OptimizerResult reference = minimize(whole, whole.start(), whole.settings());
    ASSERT_EQ(reference.reason, StopReason::GRADIENT_TOLERANCE);
    BoundedRosenbrock first(6), second(6);
    OptimizerResult stopped, resumed;
    stop_and_resume(first, second, whole.start(), whole.settings(), reference.iterations, stopped, resumed);
    EXPECT_EQ(resumed.reason, StopReason::GRADIENT_TOLERANCE) << resumed.message;
    EXPECT_EQ(resumed.iterations, reference.iterations);
    EXPECT_EQ(second.evaluations, 0);
    EXPECT_TRUE(second.iterates.empty());

    // The same with f_tolerance and x_tolerance, which need the previous f and the step.
    for (const bool use_f : { true, false }) {
        OptimizerSettings s = whole.settings();
        s.gradient_tolerance = 0;
        (use_f ? s.f_tolerance : s.x_tolerance) = use_f ? 1e-3 : 1e-2;
        BoundedRosenbrock a(6), b(6), c(6);
        const OptimizerResult full = minimize(a, a.start(), s);
        ASSERT_EQ(full.reason, use_f ? StopReason::F_TOLERANCE : StopReason::X_TOLERANCE) << full.message;
        OptimizerResult part, rest;
        stop_and_resume(b, c, b.start(), s, full.iterations, part, rest);
        EXPECT_EQ(rest.reason, full.reason) << rest.message;
        EXPECT_EQ(rest.iterations, full.iterations);
        EXPECT_EQ(c.evaluations, 0);
    }
}

TEST(OptimizerResume, IpoptAndNloptContinueFromTheLastIterateAndConverge)
{
    for (const OptimizerAlgorithm algorithm : { OptimizerAlgorithm::IPOPT, OptimizerAlgorithm::SLSQP }) {
        SCOPED_TRACE(to_string(algorithm));
        OptimizerSettings s;
        s.algorithm = algorithm;
        s.lower = VectorXd::Zero(3);
        s.upper = VectorXd::Constant(3, 5.0);
        s.gradient_tolerance = 1e-10;
        s.relative_gradient_tolerance = 0;
        s.x_tolerance = algorithm == OptimizerAlgorithm::SLSQP ? 1e-12 : 0;
        s.max_iterations = 100;
        const VectorXd x0 = Eigen::Vector3d(4, 0.5, 0.5);
        ConstrainedQuadratic first, second;
        OptimizerResult stopped, resumed;
        stop_and_resume(first, second, x0, s, 2, stopped, resumed);
        EXPECT_TRUE(first.last.lbfgs_pairs.empty());
        EXPECT_LE((resumed.x - ConstrainedQuadratic::optimum()).lpNorm<Eigen::Infinity>(), 1e-6) << resumed.message;
        EXPECT_LE(resumed.max_violation, 1e-6);
        ASSERT_FALSE(second.iterations.empty());
        // Numbering goes on after the checkpoint's iteration; the iterate it continues from is
        // not reported again.
        EXPECT_EQ(second.iterations.front(), 3);
        for (size_t i = 1; i < second.iterations.size(); ++i)
            EXPECT_EQ(second.iterations[i], second.iterations[i - 1] + 1);
        EXPECT_EQ(resumed.iterations, second.iterations.back());
        EXPECT_EQ(resumed.evaluations, first.last.evaluations + second.evaluations);

        // A spent budget ends a resumed run before the library starts.
        OptimizerSettings spent = s;
        spent.max_iterations = 2;
        ConstrainedQuadratic third;
        const OptimizerResult r = resume_minimize(third, first.last, spent);
        EXPECT_EQ(r.reason, StopReason::ITERATION_BUDGET);
        EXPECT_EQ(r.iterations, 2);
        EXPECT_EQ(third.evaluations, 0);
    }
}

TEST(OptimizerResume, TimesGoOnFromTheCheckpoint)
{
    BoundedRosenbrock first(4), second(4);
    OptimizerSettings s = first.settings();
    first.stop_at = 3;
    minimize(first, first.start(), s);
    OptimizerCheckpoint c = first.last;
    c.elapsed_seconds = 100; // as if the first part had taken 100 s
    c.evaluation_seconds = 60;
    c.optimizer_seconds = 30;
    c.optimizer_cpu_seconds = 20;
    s.max_seconds = 50; // spent already
    const OptimizerResult r = resume_minimize(second, c, s);
    EXPECT_EQ(r.reason, StopReason::TIME_BUDGET) << r.message;
    EXPECT_EQ(second.evaluations, 0);
    EXPECT_GE(r.evaluation_seconds, 60);
    EXPECT_GE(r.optimizer_seconds, 30);
    EXPECT_GE(r.optimizer_cpu_seconds, 20);
}

TEST(OptimizerResume, ACheckpointThatDoesNotFitIsRefused)
{
    BoundedRosenbrock first(4);
    first.stop_at = 2;
    minimize(first, first.start(), first.settings());
    const auto field = [](OptimizationProblem& p, const OptimizerCheckpoint& c, const OptimizerSettings& s) {
        try {
            resume_minimize(p, c, s);
        } catch (const InputError& e) {
            return e.field();
        }
        return std::string();
    };
    BoundedRosenbrock other(4), larger(6);
    OptimizerSettings ipopt = first.settings();
    ipopt.algorithm = OptimizerAlgorithm::IPOPT;
    EXPECT_EQ(field(other, first.last, ipopt), "optimizer.algorithm");
    // A checkpoint of 4 variables for a problem of 6: the x is refused as any x0 of the wrong size.
    EXPECT_EQ(field(larger, first.last, larger.settings()), "optimizer.x0");
    OptimizerCheckpoint bad = first.last;
    bad.values.gradient.resize(3);
    EXPECT_EQ(field(other, bad, first.settings()), "optimizer.checkpoint");
    bad = first.last;
    bad.lbfgs_pairs.front().y[0] = std::nan("");
    EXPECT_EQ(field(other, bad, first.settings()), "optimizer.checkpoint");
    bad = first.last;
    bad.optimizer_cpu_seconds = -1;
    EXPECT_EQ(field(other, bad, first.settings()), "optimizer.checkpoint");
}

} // namespace
