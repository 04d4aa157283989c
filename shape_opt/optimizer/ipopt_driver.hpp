#pragma once
/// @file ipopt_driver.hpp
/// Ipopt (OptimizerAlgorithm::IPOPT, Ipopt 3.11 as Debian ships it) on an OptimizationProblem:
/// the interior-point method with a limited-memory quasi-Newton Hessian
/// (hessian_approximation limited-memory, limited_memory_max_history = lbfgs_memory) and the
/// inequalities c(x) <= 0 and equalities h(x) = 0 as true constraints (dense Jacobians).
///
/// Settings: tol = max(gradient_tolerance, relative_gradient_tolerance * the initial projected
/// gradient's inf-norm) (Ipopt's own default 1e-8 when both are 0); constr_viol_tol =
/// constraint_tolerance; max_iter = max_iterations; max_cpu_time = max_seconds (the wall time
/// is checked too); print_level 0 and no banner; mumps_mem_percent 100 (MUMPS's workspace;
/// Ipopt's 1000 only slows the factorizations of small systems, see ipopt_driver.cpp).
/// x_tolerance and f_tolerance are checked at each iteration whose constraint violation is
/// within constraint_tolerance. settings.options are set afterwards and override these; an
/// ipopt.opt file in the working directory is not read.
///
/// Ipopt asks for f, its gradient, c and h and their Jacobians separately: they come from one
/// evaluate() per point (a small cache keyed by x). At an invalid point the eval_* calls
/// return false and Ipopt cuts its step back; max_valid_step() is not used.
///
/// A resumed run (resume_minimize) starts Ipopt afresh at the checkpoint's x, with the values
/// stored there (a warm start of x only: Ipopt's multipliers, barrier parameter and quasi-Newton
/// memory start anew, so its iterates differ from an uninterrupted run's). Ipopt's iteration i
/// is reported as the checkpoint's iteration + i (its iteration 0, the point resumed from, is
/// not reported again); tol keeps the first run's initial gradient; max_iter and max_cpu_time
/// are what is left of the budgets.

#include "shape_opt/optimizer/optimizer.hpp"

namespace diffipc {

/// @brief Runs Ipopt from a valid x0 (called by minimize() after validation).
/// @param run      the run, whose first evaluation was x0
/// @param x0       n initial values inside the bounds
/// @param values0  the values at x0
OptimizerResult minimize_ipopt(optimizer_detail::Run& run, const VectorXd& x0, const OptimizationValues& values0);

/// @brief Checks settings.options against Ipopt's registered options: each must exist and its
/// value must read as the option's type (number, integer, string) within its valid values.
/// @throws InputError naming "optimizer.options.<name>"
void check_ipopt_options(const OptimizerSettings& settings);

} // namespace diffipc
