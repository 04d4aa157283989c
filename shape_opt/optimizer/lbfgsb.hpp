#pragma once
/// @file lbfgsb.hpp
/// Projected L-BFGS with bounds (OptimizerAlgorithm::LBFGSB; LBFGS is the same without bounds).
///
/// Each iteration splits the variables into an active set, those at (within 1e-6 relative of) a
/// bound whose gradient points out of the box, and the free rest. The direction is the L-BFGS
/// two-loop recursion (Nocedal & Wright, Numerical Optimization, 2nd ed., Algorithm 7.4) on the
/// free variables and the scaled steepest descent on the active ones (the two-metric projection
/// of Bertsekas, SIAM J. Control Optim. 20(2), 1982); the line search backtracks along the
/// projected path P(x + t d) until the Armijo condition f(x_t) <= f(x) + 1e-4 g.(x_t - x) holds.
///
/// Validity: the first trial and every later one is cut to 0.99 of problem.max_valid_step(x, dx)
/// (so it never reaches the boundary of the valid region); a trial where evaluate() fails is
/// counted as rejected and the step halved. A correction pair is skipped when
/// s.y <= 1e-10 |s| |y| (restricted to the free variables in the recursion). A line search that
/// makes no progress in 40 trials is retried once from steepest descent with the memory cleared,
/// then ends the run with LINE_SEARCH_STALLED.
///
/// Its state between iterations is x, the values there, the correction pairs, the iteration
/// number and the initial gradient norm: the checkpoint (IterationInfo::checkpoint) holds all of
/// them, so that a resumed run (resume_minimize) repeats the checks that follow its last
/// iteration and then takes the uninterrupted run's steps, to the last bit for a deterministic
/// problem (tests/shape_opt/optimizer/test_optimizer_resume.cpp).

#include "shape_opt/optimizer/optimizer.hpp"

namespace diffipc {

/// @brief Runs projected L-BFGS from a valid x0 (called by minimize() after validation).
/// @param run      the run, whose first evaluation was x0
/// @param x0       n initial values inside the bounds
/// @param values0  the values at x0
OptimizerResult minimize_lbfgsb(optimizer_detail::Run& run, const VectorXd& x0, const OptimizationValues& values0);

} // namespace diffipc
