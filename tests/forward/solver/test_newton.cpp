// The Newton solver's step extension (forward/solver/newton.cpp, NewtonSolver::Run::extend) on a model
// of a structure at a bifurcation: an energy whose true curvature is 1000 times smaller than that
// of its search matrix (what a per-element PSD projection does where the true Hessian is
// indefinite or nearly singular). Full steps then take almost the whole decrease the gradient
// predicts and move 1/1000 of the way each: without the extension the solve creeps for thousands
// of iterations. With it the solve converges in a few; an extended step never passes the bound a
// potential's max_step sets (checked at every accepted iterate, independently of the solver); and a
// search matrix that is the exact curvature takes plain Newton steps, never extended.

#include "forward/scene/scene.hpp"
#include "forward/solver/linear_solver.hpp"
#include "forward/solver/newton.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace diffipc;

namespace {

/// E(x) = k/2 sum_i (x_i - 1)^2 over the dofs of one triangle (2D); the search matrix is
/// `search` * I; finite only for x_i < wall, and max_step stops every dof before the wall.
class Creep : public Potential {
public:
    Creep(double k, double search, double wall)
        : m_k(k)
        , m_search(search)
        , m_wall(wall)
    {
    }
    std::string name() const override { return "creep"; }
    double value(const VectorXd& x) const override
    {
        if ((x.array() >= m_wall).any())
            return INFINITY;
        return 0.5 * m_k * (x.array() - 1).square().sum();
    }
    void add_gradient(const VectorXd& x, double weight, VectorXd& g) const override
    {
        g += weight * m_k * (x.array() - 1).matrix();
    }
    void add_hessian(const VectorXd& x, double weight, bool project_to_psd, SparseAssembler& H) const override
    {
        const MatrixXd K = weight * (project_to_psd ? m_search : m_k) * MatrixXd::Identity(x.size(), x.size());
        H.add_element(0, K.data());
    }
    double max_step(const VectorXd& x, const VectorXd& p) const override
    {
        double t = 1.0;
        for (Index i = 0; i < x.size(); ++i)
            if (p[i] > 0)
                t = std::min(t, 0.9 * (m_wall - x[i]) / p[i]);
        return t;
    }
    bool end_iteration(const VectorXd& x) override
    {
        largest = std::max(largest, x.maxCoeff());
        return false;
    }
    double largest = -INFINITY; ///< over the accepted iterates

private:
    double m_k, m_search, m_wall;
};

struct Solve {
    NewtonResult result;
    VectorXd x;
    double largest;
};

Solve solve(double k, double search, double wall, bool adaptive_projection, bool extension = true)
{
    Creep creep(k, search, wall);
    Problem problem;
    problem.add(&creep, 1.0);
    SparseAssembler assembler;
    MatrixXi triangle(1, 3);
    triangle << 0, 1, 2;
    assembler.build(2, 3, triangle, false);
    LinearSolver linear(LinearSolverType::CHOLMOD);
    NewtonSettings settings;
    settings.max_iterations = 100;
    settings.adaptive_projection = adaptive_projection;
    settings.step_extension = extension;
    const NewtonSolver newton(problem, assembler, linear, settings);
    Solve s;
    s.x = VectorXd::Zero(6);
    const VectorXd target = s.x;
    s.result = newton.solve(s.x, target, std::vector<char>(6, 0), 1.0, 1.0);
    s.largest = creep.largest;
    return s;
}

} // namespace

TEST(NewtonExtension, ACreepingSolveConvergesInAFewIterations)
{
    // Search curvature 1000, true curvature 1: a plain full step moves 1/1000 of the remaining
    // distance (the residual would take about 18,000 iterations to fall from 1 to 1e-8).
    const Solve creeping = solve(1.0, 1000.0, 10.0, false, false);
    EXPECT_EQ(creeping.result.status, StepStatus::NEWTON_EXHAUSTED);
    EXPECT_EQ(creeping.result.extended_steps, 0);
    EXPECT_GT(creeping.result.residual, 0.5); // 100 steps of 1/1000: 0.999^100 = 0.905 of the way left
    const Solve s = solve(1.0, 1000.0, 10.0, false);
    ASSERT_EQ(s.result.status, StepStatus::CONVERGED);
    EXPECT_LE(s.result.iterations, 20);
    EXPECT_GE(s.result.extended_steps, 1);
    EXPECT_LT((s.x.array() - 1).abs().maxCoeff(), 1e-8);
}

TEST(NewtonExtension, ExtendedStepsStopAtTheAdmissibleBound)
{
    // The wall at 1.01, just beyond the minimizer: the doubling (which would reach 1.024 from 0)
    // is cut by max_step, and every accepted iterate stays below the wall.
    const Solve s = solve(1.0, 1000.0, 1.01, false);
    ASSERT_EQ(s.result.status, StepStatus::CONVERGED);
    EXPECT_LT(s.largest, 1.01);
    EXPECT_GE(s.result.extended_steps, 1);
    EXPECT_LT((s.x.array() - 1).abs().maxCoeff(), 1e-8);
}

TEST(NewtonExtension, AnExactSearchMatrixIsNeverExtended)
{
    for (bool adaptive : { false, true }) {
        const Solve s = solve(1.0, 1.0, 10.0, adaptive);
        ASSERT_EQ(s.result.status, StepStatus::CONVERGED);
        EXPECT_EQ(s.result.iterations, 1); // one Newton step solves a quadratic
        EXPECT_EQ(s.result.extended_steps, 0);
        EXPECT_LT((s.x.array() - 1).abs().maxCoeff(), 1e-12);
    }
}
