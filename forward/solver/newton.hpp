#pragma once
/// @file newton.hpp
/// Projected Newton on the incremental potential with Dirichlet lifting,
/// inversion-bounded backtracking line search and separate convergence measures.

#include "forward/solver/linear_solver.hpp"
#include "forward/solver/problem.hpp"
#include "forward/solver/status.hpp"

#include <algorithm>
#include <vector>

namespace diffipc {

struct NewtonSettings {
    double residual_tolerance = 1e-8;
    double step_tolerance = 0; ///< 0: not used
    int max_iterations = 100;
    int line_search_max_halvings = 40;
    double armijo = 1e-4;
    /// Use the true Hessian once a full step was accepted, as long as it is
    /// positive definite (docs/math.md "Newton"); false: always project.
    bool adaptive_projection = true;
    /// Lengthen a full step along which the energy fell almost linearly (newton.cpp, NewtonSolver::Run::extend;
    /// docs/math.md "Step extension"); false: never.
    bool step_extension = true;
    /// Largest displacement (m, max norm over the free dofs) one line search tries; a longer
    /// Newton step is shortened to it before CCD sweeps it (prescribed dofs do not count:
    /// lifting moves them as far as the prescription says). 0: unbounded. The simulator sets
    /// the bodies' bounding-box diagonal plus the step's inertial drift for contact scenes: a
    /// step of 1e15 m (a rigid mode of a static scene, a huge load or dt) otherwise sweeps
    /// every pair across the scene and CCD spends its whole iteration budget on each.
    double max_displacement = 0;
};

struct NewtonResult {
    StepStatus status = StepStatus::NEWTON_EXHAUSTED;
    int iterations = 0; ///< Newton steps taken
    double residual = 0; ///< max |free-dof gradient| / force scale, at the last iterate
    double newton_step = 0; ///< max |last step| / step scale
    int linear_fallbacks = 0; ///< factorizations that needed LDL^T
    int gradient_steps = 0; ///< iterations that fell back to the negative gradient
    int true_hessian_steps = 0; ///< iterations that used the unprojected (positive definite) Hessian
    /// Full steps lengthened because the energy fell almost linearly along them (NewtonSolver::Run::extend).
    int extended_steps = 0;
    /// Line-search halvings of the accepted steps (a step that CCD or the inversion bound
    /// shortened first counts only the halvings after that).
    int line_search_cuts = 0;
    /// Converged because the full Newton step fell below the round-off of x
    /// while the residual was still above its tolerance.
    bool roundoff_limited = false;
    PhaseTimes times;
    /// Adds another solve's iterations, LDL^T fallbacks and times to this one's.
    void add_costs(const NewtonResult& r)
    {
        iterations += r.iterations;
        linear_fallbacks += r.linear_fallbacks;
        line_search_cuts += r.line_search_cuts;
        times += r.times;
    }
    /// This result (status, residual, ...) with the iterations, fallbacks and times of `total`:
    /// a sequence of solves reported as one.
    NewtonResult with_costs_of(const NewtonResult& total) const
    {
        NewtonResult r = *this;
        r.iterations = total.iterations;
        r.linear_fallbacks = total.linear_fallbacks;
        r.line_search_cuts = total.line_search_cuts;
        r.times = total.times;
        return r;
    }
};

/// A linear constraint a^T x = level on the free dofs for displacement control (load_stepping.cpp):
/// the solve minimizes the energy on the constraint surface, and the constraint's multiplier is
/// the load along a that the converged state carries.
struct LoadControl {
    VectorXd direction; ///< a (#dofs, zero on constrained dofs)
    double level = 0; ///< a^T x at the solution
    double tolerance = 0; ///< |a^T x - level| below which the constraint holds
    double multiplier = 0; ///< out: lambda with grad E = lambda a at the last iterate (least squares)
};

class NewtonSolver {
public:
    NewtonSolver(const Problem& problem, SparseAssembler& assembler, LinearSolver& linear, NewtonSettings settings)
        : m_problem(problem)
        , m_assembler(assembler)
        , m_linear(linear)
        , m_settings(settings)
    {
    }

    /// @brief Minimizes the problem's energy over the free dofs, moving the
    /// constrained dofs to their targets first ("lifting" iterations whose
    /// step is only bounded, not Armijo-tested, since the constraint changes).
    /// @param x           in: start (feasible); out: last iterate
    /// @param target      #dofs, target values of the constrained dofs
    /// @param constrained #dofs flags
    /// @param force_scale the residual is max|g_free| / force_scale
    /// @param step_scale  the Newton step is max|alpha p| / step_scale
    /// @param control     if given: minimize on the surface a^T x = level (reached like
    ///                    prescribed values, by steps bounded only by CCD and inversion); the
    ///                    residual is then that of grad E - lambda a, and control->multiplier is set
    NewtonResult solve(VectorXd& x, const VectorXd& target, const std::vector<char>& constrained, double force_scale,
        double step_scale, LoadControl* control = nullptr) const;

    const NewtonSettings& settings() const { return m_settings; }

    /// The same solver with at most `max_iterations` per solve.
    NewtonSolver limited(int max_iterations) const
    {
        NewtonSettings s = m_settings;
        s.max_iterations = std::min(s.max_iterations, max_iterations);
        return NewtonSolver(m_problem, m_assembler, m_linear, s);
    }

private:
    struct Run; ///< one solve's state and steps (newton.cpp)

    const Problem& m_problem;
    SparseAssembler& m_assembler;
    LinearSolver& m_linear;
    NewtonSettings m_settings;
};

} // namespace diffipc
