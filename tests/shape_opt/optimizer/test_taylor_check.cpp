// The final Taylor check (shape_opt/optimizer/taylor_check.hpp): its verdict on a smooth f (one
// whose remainder changes sign between steps too), a kink and a jump at the point, on a constant
// or linear f and on rejected points; its direction scaled per variable, kept inside the bounds
// and its first step within max_valid_step().

#include "forward/common/error.hpp"
#include "shape_opt/optimizer/taylor_check.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>

using namespace diffipc;

namespace {

constexpr double INF = std::numeric_limits<double>::infinity();

/// f and its gradient from lambdas; points where `invalid` holds are rejected.
class FunctionProblem : public OptimizationProblem {
public:
    FunctionProblem(Index n, std::function<double(const VectorXd&)> f, std::function<VectorXd(const VectorXd&)> g)
        : m_n(n)
        , m_f(std::move(f))
        , m_g(std::move(g))
    {
    }
    Index size() const override { return m_n; }
    double max_valid_step(const VectorXd& x, const VectorXd& dx) override
    {
        return valid_step ? valid_step(x, dx) : 1.0;
    }
    bool evaluate(const VectorXd& x, OptimizationValues& out) override
    {
        ++evaluations;
        points.push_back(x);
        if (invalid && invalid(x))
            return false;
        out.f = m_f(x);
        out.gradient = m_g(x);
        return true;
    }
    OptimizationValues at(const VectorXd& x)
    {
        OptimizationValues v;
        v.f = m_f(x);
        v.gradient = m_g(x);
        return v;
    }
    std::function<bool(const VectorXd&)> invalid;
    std::function<double(const VectorXd&, const VectorXd&)> valid_step;
    int evaluations = 0;
    std::vector<VectorXd> points;

private:
    Index m_n;
    std::function<double(const VectorXd&)> m_f;
    std::function<VectorXd(const VectorXd&)> m_g;
};

const VectorXd FREE_LOWER = VectorXd::Constant(3, -INF), FREE_UPPER = VectorXd::Constant(3, INF);

TaylorCheck check_at(FunctionProblem& p, const VectorXd& x, const VectorXd& lower = FREE_LOWER,
    const VectorXd& upper = FREE_UPPER, TaylorCheckSettings s = {})
{
    return final_taylor_check(p, x, p.at(x), lower, upper, VectorXd::Ones(x.size()), s);
}

/// A problem of one variable whose f along the check's direction is phi(h) at x0 + h d
/// (phi(0) = 0, phi'(0) given): f(x) = phi((x - x0) / d), d the direction the seed gives.
TaylorCheck check_along(std::function<double(double)> phi, double slope, TaylorCheckSettings s = {})
{
    const VectorXd x0 = VectorXd::Constant(1, 0.3), free_lo = VectorXd::Constant(1, -INF),
                   free_hi = VectorXd::Constant(1, INF);
    FunctionProblem probe(
        1, [](const VectorXd& x) { return x[0]; }, [](const VectorXd&) { return VectorXd(VectorXd::Ones(1)); });
    const double d = check_at(probe, x0, free_lo, free_hi, s).direction[0];
    FunctionProblem p(
        1, [=](const VectorXd& x) { return 1 + phi((x[0] - x0[0]) / d); },
        [=](const VectorXd&) { return VectorXd(VectorXd::Constant(1, slope / d)); });
    // The gradient is only read at x0.
    return check_at(p, x0, free_lo, free_hi, s);
}

} // namespace

TEST(TaylorCheck, SmoothObjectiveIsSmooth)
{
    FunctionProblem p(
        3, [](const VectorXd& x) { return std::exp(x[0]) + x[1] * x[1] * x[2] + 3 * x[2] * x[2]; },
        [](const VectorXd& x) { return Eigen::Vector3d(std::exp(x[0]), 2 * x[1] * x[2], x[1] * x[1] + 6 * x[2]); });
    TaylorCheckSettings s;
    s.step = 0.01;
    const TaylorCheck c = check_at(p, Eigen::Vector3d(0.3, -1.2, 2), FREE_LOWER, FREE_UPPER, s);
    EXPECT_EQ(c.verdict, "smooth") << c.reason;
    EXPECT_EQ(c.evaluations, 4);
    EXPECT_EQ(p.evaluations, 4);
    ASSERT_EQ(c.rates.size(), 3u);
    for (double r : c.rates)
        EXPECT_NEAR(r, 2, 0.1);
}

// f = |x0 - 1| + x1^2 at x0 = 1, where the gradient given is the subgradient 0 in x0: the
// remainder falls like h (rate 1) on either side.
TEST(TaylorCheck, KinkAtThePointIsNonSmooth)
{
    FunctionProblem p(
        3, [](const VectorXd& x) { return std::abs(x[0] - 1) + x[1] * x[1]; },
        [](const VectorXd& x) { return Eigen::Vector3d(x[0] > 1 ? 1.0 : (x[0] < 1 ? -1.0 : 0.0), 2 * x[1], 0); });
    const TaylorCheck c = check_at(p, Eigen::Vector3d(1, 0.5, 0));
    EXPECT_EQ(c.verdict, "non_smooth") << c.reason;
    EXPECT_NEAR(c.rates.back(), 1, 0.2);
}

// f jumps by 0.1 next to the point, on the side the direction goes (it is the same for
// either sign of d0: the jump surrounds the point): the remainder does not fall (rate 0).
TEST(TaylorCheck, JumpNextToThePointIsNonSmooth)
{
    FunctionProblem p(
        3, [](const VectorXd& x) { return x.squaredNorm() + (std::abs(x[0] - 0.5) > 1e-9 ? 0.1 : 0.0); },
        [](const VectorXd& x) { return VectorXd(2 * x); });
    const TaylorCheck c = check_at(p, Eigen::Vector3d(0.5, 0.2, -0.1));
    EXPECT_EQ(c.verdict, "non_smooth") << c.reason;
    EXPECT_NEAR(c.rates.back(), 0, 0.2);
}

// A jump between the first and second step: the remainder falls by far more than h^2 once.
TEST(TaylorCheck, JumpCrossedByTheLargestStepIsNonSmooth)
{
    const Eigen::Vector3d x0(0.4, 0.2, -0.1);
    const auto g = [](const VectorXd& x) { return VectorXd(2 * x); };
    FunctionProblem smooth(
        3, [](const VectorXd& x) { return x.squaredNorm(); }, g);
    const double first = TaylorCheckSettings().step * check_at(smooth, x0).direction.norm(); // same seed
    FunctionProblem p(
        3, [&](const VectorXd& x) { return x.squaredNorm() + ((x - x0).norm() > 0.75 * first ? 0.05 : 0.0); }, g);
    const TaylorCheck c = check_at(p, x0);
    EXPECT_EQ(c.verdict, "non_smooth") << c.reason;
    EXPECT_NE(c.reason.find("crosses a jump or kink"), std::string::npos) << c.reason;
}

// phi(h) = h^2 - 182 h^3 is smooth, but at h = 0.01 its cubic term outweighs the quadratic one:
// R = -8.2e-5 there, 2.25e-6 at 0.005, |R| falls by 2^5.2 in one halving and rises in the next.
// R/h^2 (-0.82, 0.09, 0.545, 0.77) settles: its changes halve with h.
TEST(TaylorCheck, RemainderChangingSignIsSmooth)
{
    TaylorCheckSettings s;
    s.step = 0.01;
    const TaylorCheck c = check_along([](double h) { return h * h - 182 * h * h * h; }, 0, s);
    EXPECT_EQ(c.verdict, "smooth") << c.reason;
    EXPECT_LT(c.remainders[0], 0);
    EXPECT_GT(c.remainders[1], 0);
    EXPECT_GT(c.rates[0], 5);
    for (double r : c.settle_rates)
        EXPECT_NEAR(r, 3, 1e-6);
}

TEST(TaylorCheck, AbsoluteValueKinkIsNonSmooth)
{
    const TaylorCheck c = check_along([](double h) { return std::abs(h) + h * h; }, 0);
    EXPECT_EQ(c.verdict, "non_smooth") << c.reason;
    EXPECT_NEAR(c.settle_rates.back(), 1, 1e-6);
}

TEST(TaylorCheck, StepFunctionJumpIsNonSmooth)
{
    const TaylorCheck c = check_along([](double h) { return h * h + (h > 0 ? 1e-3 : 0.0); }, 0);
    EXPECT_EQ(c.verdict, "non_smooth") << c.reason;
    EXPECT_NEAR(c.settle_rates.back(), 0, 1e-6);
}

TEST(TaylorCheck, ExactQuadraticIsSmooth)
{
    const TaylorCheck c = check_along([](double h) { return 3 * h + 0.5 * h * h; }, 3);
    EXPECT_EQ(c.verdict, "smooth") << c.reason;
}

// No smooth verdict without two resolved rates: a linear f (no remainder above round-off), and a
// curvature so small that only the two largest steps resolve their remainders (the resolution
// is 100 x 1e-10 |f| = 1e-8 here).
TEST(TaylorCheck, FewerThanTwoResolvedRatesIsInconclusive)
{
    const TaylorCheck linear = check_along([](double h) { return 2 * h; }, 2);
    EXPECT_EQ(linear.verdict, "inconclusive") << linear.reason;
    const double h0 = TaylorCheckSettings().step;
    const TaylorCheck faint = check_along([&](double h) { return 5e-8 * (h / h0) * (h / h0); }, 0);
    ASSERT_TRUE(std::isfinite(faint.rates[0]));
    ASSERT_FALSE(std::isfinite(faint.rates[1]));
    EXPECT_EQ(faint.verdict, "inconclusive") << faint.reason;
}

// Each variable's direction within [-1, 1] times its scale (diffipc gradcheck's), and the steps
// within the problem's valid ones (max_valid_step()), as the optimizers' steps.
TEST(TaylorCheck, DirectionFollowsTheScalesAndTheValidSteps)
{
    FunctionProblem p(
        3, [](const VectorXd& x) { return x.squaredNorm(); }, [](const VectorXd& x) { return VectorXd(2 * x); });
    const Eigen::Vector3d x(1, 2, 3), scales(1e-3, 5, 1);
    const TaylorCheck c = final_taylor_check(p, x, p.at(x), FREE_LOWER, FREE_UPPER, scales, TaylorCheckSettings());
    EXPECT_TRUE((c.direction.array().abs() <= scales.array()).all()) << c.direction.transpose();
    EXPECT_TRUE((c.direction.array() != 0).all());
    // Points beyond a quarter of the first step are invalid: the step is cut, none is rejected.
    p.valid_step = [](const VectorXd&, const VectorXd&) { return 0.25; };
    p.invalid = [&](const VectorXd& y) { return (y - x).norm() > 0.25 * 0.1 * c.direction.norm(); };
    const TaylorCheck cut = final_taylor_check(p, x, p.at(x), FREE_LOWER, FREE_UPPER, scales, TaylorCheckSettings());
    EXPECT_EQ(cut.rejected, 0);
    EXPECT_DOUBLE_EQ(cut.steps[0], 0.1 * 0.25 * TAYLOR_VALID_FRACTION);
    EXPECT_EQ(cut.verdict, "smooth") << cut.reason;
    EXPECT_THROW(final_taylor_check(p, x, p.at(x), FREE_LOWER, FREE_UPPER, VectorXd::Ones(2), TaylorCheckSettings()),
        std::invalid_argument);
}

TEST(TaylorCheck, StopEndsItInconclusive)
{
    FunctionProblem p(
        3, [](const VectorXd& x) { return x.squaredNorm(); }, [](const VectorXd& x) { return VectorXd(2 * x); });
    const Eigen::Vector3d x(1, 2, 3);
    const TaylorCheck c = final_taylor_check(p, x, p.at(x), FREE_LOWER, FREE_UPPER, VectorXd::Ones(3),
        TaylorCheckSettings(), [&] { return p.evaluations >= 2; });
    EXPECT_TRUE(c.stopped);
    EXPECT_EQ(c.evaluations, 2);
    EXPECT_EQ(c.verdict, "inconclusive") << c.reason;
}

TEST(TaylorCheck, ConstantObjectiveIsInconclusive)
{
    FunctionProblem p(
        3, [](const VectorXd&) { return 2.0; }, [](const VectorXd&) { return VectorXd(VectorXd::Zero(3)); });
    EXPECT_EQ(check_at(p, Eigen::Vector3d(1, 2, 3)).verdict, "inconclusive");
}

TEST(TaylorCheck, RejectedPointsAreCountedAndLeaveItInconclusive)
{
    FunctionProblem p(
        3, [](const VectorXd& x) { return x.squaredNorm(); }, [](const VectorXd& x) { return VectorXd(2 * x); });
    p.invalid = [](const VectorXd&) { return true; };
    const TaylorCheck c = check_at(p, Eigen::Vector3d(1, 2, 3));
    EXPECT_EQ(c.verdict, "inconclusive");
    EXPECT_EQ(c.rejected, 4);
    EXPECT_TRUE(std::isnan(c.remainders.front()));
}

// Every point of the test inside the box: a variable on its upper bound is moved down, one in
// a box narrower than the step is held.
TEST(TaylorCheck, DirectionStaysInsideTheBounds)
{
    FunctionProblem p(
        3, [](const VectorXd& x) { return x.squaredNorm(); }, [](const VectorXd& x) { return VectorXd(2 * x); });
    const Eigen::Vector3d lower(0, -1, 0.5), upper(1, 1, 0.5);
    for (unsigned seed = 1; seed <= 8; ++seed) {
        TaylorCheckSettings s;
        s.seed = seed;
        p.points.clear();
        const TaylorCheck c = check_at(p, Eigen::Vector3d(1, -1, 0.5), lower, upper, s);
        EXPECT_LE(c.direction[0], 0);
        EXPECT_GE(c.direction[1], 0);
        EXPECT_EQ(c.direction[2], 0);
        for (const VectorXd& x : p.points)
            EXPECT_TRUE((x.array() >= lower.array()).all() && (x.array() <= upper.array()).all()) << x.transpose();
    }
}

TEST(TaylorCheck, BadSettingsNameTheirField)
{
    FunctionProblem p(
        3, [](const VectorXd& x) { return x.squaredNorm(); }, [](const VectorXd& x) { return VectorXd(2 * x); });
    TaylorCheckSettings s;
    s.step = 0;
    try {
        check_at(p, Eigen::Vector3d(1, 2, 3), FREE_LOWER, FREE_UPPER, s);
        FAIL() << "no error";
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), "optimizer.final_taylor_check.step");
    }
}
