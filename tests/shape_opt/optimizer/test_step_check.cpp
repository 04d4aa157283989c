// The step check of minimize() (StepJump, shape_opt/optimizer/optimizer.hpp): the count of all
// flagged steps beside the capped list, and a resumed run's step check and best point carried
// over from its checkpoint.

#include "shape_opt/optimizer/optimizer.hpp"

#include <gtest/gtest.h>

using namespace diffipc;

namespace {

/// f = x^2 / 2 (f' = x) and f jumps by 1 between every two integers: steps of 1 jump.
class Staircase : public OptimizationProblem {
public:
    Index size() const override { return 1; }
    bool evaluate(const VectorXd& x, OptimizationValues& out) override
    {
        out.f = 0.5e-6 * x[0] * x[0] + std::floor(x[0]);
        out.gradient = VectorXd::Constant(1, 1e-6 * x[0]);
        return true;
    }
};

/// Accepts x = 0, 1, ..., n as the iterates of a run (or of its resumed part, from `first`).
OptimizerResult climb(Staircase& p, int first, int last, const OptimizerCheckpoint* resume = nullptr)
{
    optimizer_detail::Run run(p, OptimizerSettings(), resume);
    OptimizationValues v;
    for (int k = first; k <= last; ++k) {
        const VectorXd x = VectorXd::Constant(1, double(k));
        if (!(resume && k == first)) {
            EXPECT_TRUE(run.evaluate(x, v));
            run.iteration(k, x, v, 1, 1);
        }
    }
    return run.finish(StopReason::ITERATION_BUDGET, "budget", last);
}

} // namespace

TEST(StepCheck, CountsEveryJumpBeyondTheKeptList)
{
    Staircase p;
    const OptimizerResult r = climb(p, 0, 25);
    EXPECT_EQ(r.steps_checked, 25);
    EXPECT_EQ(r.jumps.size(), MAX_STEP_JUMPS);
    EXPECT_EQ(r.jumps_found, 25);
}

TEST(StepCheck, ResumedRunKeepsItsJumpsCountsAndBestPoint)
{
    Staircase p;
    OptimizerCheckpoint c;
    c.iteration = 25;
    c.x = VectorXd::Constant(1, 25.0);
    p.evaluate(c.x, c.values);
    c.previous_f = c.values.f - 1;
    c.evaluations = 26;
    c.has_best = true;
    c.best_x = VectorXd::Constant(1, -3.0); // a point the resumed part does not beat
    p.evaluate(c.best_x, c.best_values);
    c.best_evaluation = 7;
    c.best_iteration = 6;
    c.jumps = { { 4, 2, 0, 1e-6, 1 } };
    c.jumps_found = 25;
    c.steps_checked = 25;
    const OptimizerResult r = climb(p, 25, 28, &c);
    EXPECT_EQ(r.steps_checked, 28);
    EXPECT_EQ(r.jumps_found, 28);
    ASSERT_EQ(r.jumps.size(), 4u);
    EXPECT_EQ(r.jumps.front().iteration, 4); // the earlier part's (the largest miss), kept
    EXPECT_EQ(r.best_x, c.best_x);
    EXPECT_EQ(r.best_evaluation, 7);
    EXPECT_EQ(r.best_iteration, 6);
}
