// The final Taylor check (shape_opt/optimizer/taylor_check.hpp): its verdict on a smooth f, a
// kink and a jump at the point, on a constant f and on rejected points, and its direction kept
// inside the bounds.

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
    return final_taylor_check(p, x, p.at(x), lower, upper, s);
}

} // namespace

TEST(TaylorCheck, SmoothObjectiveIsSmooth)
{
    FunctionProblem p(
        3, [](const VectorXd& x) { return std::exp(x[0]) + x[1] * x[1] * x[2] + 3 * x[2] * x[2]; },
        [](const VectorXd& x) { return Eigen::Vector3d(std::exp(x[0]), 2 * x[1] * x[2], x[1] * x[1] + 6 * x[2]); });
    const TaylorCheck c = check_at(p, Eigen::Vector3d(0.3, -1.2, 2));
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
    const double first = 1e-2 * check_at(smooth, x0).direction.norm(); // the same direction (seed)
    FunctionProblem p(
        3, [&](const VectorXd& x) { return x.squaredNorm() + ((x - x0).norm() > 0.75 * first ? 0.05 : 0.0); }, g);
    const TaylorCheck c = check_at(p, x0);
    EXPECT_EQ(c.verdict, "non_smooth") << c.reason;
    EXPECT_GT(c.rates.front(), TAYLOR_CROSSING_RATE);
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
