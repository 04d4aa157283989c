#pragma once
/// @file nlopt_driver.hpp
/// NLopt 2.7 (OptimizerAlgorithm::MMA, CCSAQ, SLSQP: NLOPT_LD_MMA, NLOPT_LD_CCSAQ, NLOPT_LD_SLSQP)
/// on an OptimizationProblem, with c(x) <= 0 and h(x) = 0 as vector constraints (MMA and CCSAQ
/// take inequalities only). f, c and h at a point come from one evaluate() (NLopt asks for them
/// separately).
///
/// NLopt counts evaluations, not iterations. Here an iteration is an evaluation at a valid point
/// that improves on the best one so far: a lower f among points within constraint_tolerance of
/// the constraints, or, before the first such point, a lower violation. problem.iteration() is
/// called from inside the objective at each one, and max_iterations counts them.
///
/// Stopping rules: f_tolerance -> ftol_rel, x_tolerance -> xtol_abs (every variable),
/// max_seconds -> maxtime (and the wall time checked at each evaluation), max_iterations as
/// above; the gradient rules apply to problems without constraints (the projected gradient at
/// each new best point): NLopt has no Lagrange multipliers to offer. Two guards end runs that
/// would never end with the tolerances at 0: 200 evaluations without a new best point
/// (LINE_SEARCH_STALLED), and NLopt asking for one point 21 times in a row (X_TOLERANCE at a
/// valid point, LINE_SEARCH_STALLED at an invalid one: CCSA's rho overflows after repeated
/// invalid trials). A stop of ours ends NLopt through force_stop. MMA and CCSAQ place their
/// asymptotes from the bounds: give finite ones (with infinite bounds MMA may stall ~1e-6 away).
///
/// Invalid points: NLopt never sees a NaN (the CCSA methods stall on it). Where evaluate() fails
/// the objective returns a large finite value, above every valid f seen
/// (f_max + 1e3 (|f_max| + |f_best| + 1)), with the last valid gradient, and each constraint a
/// violated value (max(c, 0) + 1e3 (|c| + 1), from the last valid c) with the last valid Jacobian.
/// CCSA's conservative check then fails and it retries closer to the iterate; SLSQP's line
/// search backtracks. max_valid_step() is not used.
///
/// A resumed run (resume_minimize) starts NLopt afresh at the checkpoint's x, which is the
/// best point so far (a warm start: MMA's asymptotes and SLSQP's quasi-Newton matrix start
/// anew, so its iterates differ from an uninterrupted run's); the iterations are counted on
/// from the checkpoint's, maxtime is what is left of max_seconds.

#include "shape_opt/optimizer/optimizer.hpp"

namespace diffipc {

/// @brief Runs the settings' NLopt algorithm from a valid x0 (called by minimize() after validation).
/// @param run      the run, whose first evaluation was x0
/// @param x0       n initial values inside the bounds
/// @param values0  the values at x0
OptimizerResult minimize_nlopt(optimizer_detail::Run& run, const VectorXd& x0, const OptimizationValues& values0);

/// @brief Checks settings.options: "maxeval" (integer >= 0), "xtol_rel", "ftol_abs", "stopval"
/// (numbers), and for MMA/CCSAQ "inner_maxeval", "dual_maxeval", "verbosity" (integers >= 0),
/// "dual_ftol_rel", "dual_ftol_abs" (numbers >= 0), "dual_algorithm" (an NLopt algorithm name
/// such as "LD_MMA", or its number).
/// @throws InputError naming "optimizer.options.<name>"
void check_nlopt_options(const OptimizerSettings& settings);

} // namespace diffipc
