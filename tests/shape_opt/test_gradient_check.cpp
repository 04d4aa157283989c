// shape_opt/gradient_check.hpp: the verdict of one gradcheck direction on functions whose
// derivative is known, smooth and with kinks, with right and wrong "adjoint" slopes.

#include "shape_opt/gradient_check.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

using namespace diffipc;

namespace {
constexpr double STEP = 0.1;
constexpr int HALVINGS = 4;

double smooth(double h) { return 2 * std::exp(0.3 * h) + std::sin(h); }
constexpr double SMOOTH_SLOPE = 0.6 + 1.0;

/// A quadratic exterior penalty w max(0, h - at)^2 on top of the smooth part: C^1, j'' jumps by
/// 2 w at h = at (the exterior penalty of a constraint whose bound is reached at h = at).
double penalized(double h, double at = 0, double w = 50) { return smooth(h) + w * std::pow(std::max(0.0, h - at), 2); }
} // namespace

TEST(GradientCheck, SmoothRightSlopePassesCentrally)
{
    const DirectionCheck c = check_direction(smooth, smooth(0), SMOOTH_SLOPE, STEP, HALVINGS);
    EXPECT_EQ(c.verdict, DirectionVerdict::PASS);
    EXPECT_FALSE(c.one_sided);
    EXPECT_LT(c.central_error, GRADIENT_CHECK_TOLERANCE);
    EXPECT_EQ(c.taylor.size(), size_t(HALVINGS + 1));
    EXPECT_NEAR(c.last_rate, 2.0, 0.05);
}

TEST(GradientCheck, SmoothWrongSlopeFails)
{
    const DirectionCheck c = check_direction(smooth, smooth(0), SMOOTH_SLOPE * (1 + 1e-3), STEP, HALVINGS);
    EXPECT_EQ(c.verdict, DirectionVerdict::FAIL);
    EXPECT_NEAR(c.forward, SMOOTH_SLOPE, 1e-6);
    EXPECT_NEAR(c.backward, SMOOTH_SLOPE, 1e-6);
}

TEST(GradientCheck, RightSlopeAtAKinkOfTheSecondDerivativePassesOneSided)
{
    // Before: the central difference, off by (j''(0+) - j''(0-)) h / 6, failed this right slope.
    const auto j = [](double h) { return penalized(h); };
    const DirectionCheck c = check_direction(j, j(0), SMOOTH_SLOPE, STEP, HALVINGS);
    EXPECT_GT(c.central_error, 1e-2); // the straddling central difference is off
    EXPECT_TRUE(c.one_sided);
    EXPECT_LT(c.forward_error, 1e-8);
    EXPECT_LT(c.backward_error, 1e-8);
    EXPECT_EQ(c.verdict, DirectionVerdict::PASS_AT_KINK);
    EXPECT_TRUE(passed(c.verdict));
}

TEST(GradientCheck, KinkOffTheCentreButInsideTheStepsPasses)
{
    // The bound is reached at h = 0.04: the central difference and the coarse forward steps cross
    // it, the finest forward steps (0.025 and below) do not.
    const auto j = [](double h) { return penalized(h, 0.04); };
    const DirectionCheck c = check_direction(j, j(0), SMOOTH_SLOPE, STEP, HALVINGS);
    EXPECT_EQ(c.verdict, DirectionVerdict::PASS_AT_KINK);
}

TEST(GradientCheck, WrongSlopeAtAKinkStillFails)
{
    const auto j = [](double h) { return penalized(h); };
    for (const double error : { 1e-2, 1e-4 }) {
        const DirectionCheck c = check_direction(j, j(0), SMOOTH_SLOPE * (1 + error), STEP, HALVINGS);
        EXPECT_EQ(c.verdict, DirectionVerdict::FAIL) << error;
        EXPECT_FALSE(passed(c.verdict));
    }
    // A slope of the wrong side's second derivative is no help either.
    const DirectionCheck c = check_direction(j, j(0), SMOOTH_SLOPE + 50 * STEP, STEP, HALVINGS);
    EXPECT_EQ(c.verdict, DirectionVerdict::FAIL);
}

TEST(GradientCheck, KinkOfTheFunctionItselfCannotBeChecked)
{
    // |h|: the one-sided slopes are SMOOTH_SLOPE +- 3; no slope is "the" gradient.
    const auto j = [](double h) { return smooth(h) + 3 * std::abs(h); };
    for (const double slope : { SMOOTH_SLOPE, SMOOTH_SLOPE + 3, SMOOTH_SLOPE - 3 }) {
        const DirectionCheck c = check_direction(j, j(0), slope, STEP, HALVINGS);
        EXPECT_EQ(c.verdict, DirectionVerdict::NOT_DIFFERENTIABLE) << slope;
        EXPECT_NEAR(c.forward, SMOOTH_SLOPE + 3, 1e-6);
        EXPECT_NEAR(c.backward, SMOOTH_SLOPE - 3, 1e-6);
    }
}

TEST(GradientCheck, FlatFunctionIsInconclusive)
{
    const auto j = [](double) { return 4.0; };
    EXPECT_EQ(check_direction(j, 4.0, 0.0, STEP, HALVINGS).verdict, DirectionVerdict::INCONCLUSIVE);
}

TEST(GradientCheck, EveryStepIsEvaluatedOnce)
{
    std::vector<double> steps;
    const auto j = [&](double h) {
        steps.push_back(h);
        return penalized(h);
    };
    check_direction(j, j(0), SMOOTH_SLOPE, STEP, HALVINGS);
    std::sort(steps.begin(), steps.end());
    EXPECT_EQ(std::adjacent_find(steps.begin(), steps.end()), steps.end());
    // +-2 step for the central difference, step / 2^i on both sides (i = 0..4) and 0.
    EXPECT_EQ(steps.size(), size_t(2 + 2 * (HALVINGS + 1) + 1));
}

TEST(GradientCheck, RichardsonRemovesTheFirstAndSecondOrderTerms)
{
    // D(h) = 1.5 + 7 h - 40 h^2 exactly: every second-level estimate is 1.5.
    std::vector<double> d;
    for (double h = 0.1; d.size() < 4; h /= 2)
        d.push_back(1.5 + 7 * h - 40 * h * h);
    EXPECT_NEAR(richardson_one_sided(d), 1.5, 1e-13);
    EXPECT_THROW(richardson_one_sided({ 1, 2 }), std::logic_error);
}
