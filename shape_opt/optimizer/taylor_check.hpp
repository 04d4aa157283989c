#pragma once
/// @file taylor_check.hpp
/// A short Taylor test at the point an optimization ended (issue 46): is f smooth there, as
/// every optimizer here assumes? Along one direction d, at steps h = step, step/2, ...,
/// the remainder |f(x + h d) - f(x) - h g.d| falls like h^2 where f is smooth, like h at a
/// kink (a contact active set that flips) and not at all across a jump (another equilibrium).
/// It costs halvings + 1 evaluations (each with its gradient: the problem has no cheaper one).

#include "shape_opt/optimizer/optimizer.hpp"

#include <string>
#include <vector>

namespace diffipc {

/// The verdict's thresholds on the observed rate of the remainder (log2 of its fall per halving).
constexpr double TAYLOR_SMOOTH_RATE = 1.5; ///< at least this at the smallest resolved steps: smooth
constexpr double TAYLOR_NONSMOOTH_RATE = 1.2; ///< at most this there: a kink (about 1) or a jump (about 0)
constexpr double TAYLOR_CROSSING_RATE = 4; ///< above this anywhere: the larger step crossed a jump or kink
/// Remainders below this times max(|f(x)|, 1e-300) are round-off (the forward solves' tolerance);
/// rates are taken only where both remainders exceed 100 times it.
constexpr double TAYLOR_FLOOR = 1e-10;

struct TaylorCheck {
    VectorXd direction; ///< n: d (zero in a variable held by its bounds)
    double slope = 0; ///< g.d at x
    std::vector<double> steps; ///< h, halvings + 1 of them
    std::vector<double> changes; ///< |f(x + h d) - f(x)| (NaN where the point was rejected)
    std::vector<double> remainders; ///< |f(x + h d) - f(x) - h g.d| (NaN where rejected)
    std::vector<double> rates; ///< log2(remainder(2h) / remainder(h)) from the second step on (NaN: unresolved)
    double floor = 0; ///< TAYLOR_FLOOR max(|f(x)|, 1e-300)
    std::string verdict; ///< "smooth", "non_smooth" or "inconclusive"
    std::string reason; ///< the verdict in words
    int evaluations = 0, rejected = 0;
};

/// @brief The Taylor test at x along a random direction scaled per variable and turned or zeroed
/// where the first step would leave the bounds.
/// @param x, values  the point and f, g there (n entries)
/// @param lower, upper  n bounds (+-inf for a free side)
/// @throws InputError naming "optimizer.final_taylor_check" for a step <= 0 or halvings < 1
TaylorCheck final_taylor_check(OptimizationProblem& problem, const VectorXd& x, const OptimizationValues& values,
    const VectorXd& lower, const VectorXd& upper, const TaylorCheckSettings& settings);

} // namespace diffipc
