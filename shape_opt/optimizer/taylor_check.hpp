#pragma once
/// @file taylor_check.hpp
/// A short Taylor test at the point an optimization ended (issue 46): is f smooth there, as
/// every optimizer here assumes? Along one direction d, at steps h = step, step/2, ..., the
/// signed remainder R(h) = f(x + h d) - f(x) - h g.d is A h^2 + B h^3 + ... where f is smooth,
/// c h + ... at a kink (a contact active set that flips) and a constant across a jump (another
/// equilibrium). |R| alone misleads: where A h and B h^2 are comparable R changes sign between
/// steps and |R| seems to fall by far more than 4 in one halving. The verdict is therefore on
/// R(h) - 4 R(h/2), R with its h^2 part removed (h^2 times the change of R/h^2): it falls like
/// h^3 where f is smooth, like h at a kink and not at all across a jump.
/// It costs halvings + 1 evaluations (each with its gradient: the problem has no cheaper one), up
/// to TAYLOR_EXTRA_HALVINGS more where the rates at the smallest steps disagree.

#include "shape_opt/optimizer/optimizer.hpp"

#include <functional>
#include <string>
#include <vector>

namespace diffipc {

/// The verdict's thresholds on the rate (log2 of the fall per halving) of R(h) - 4 R(h/2):
/// 3 where f is smooth, 1 at a kink, 0 across a jump.
constexpr double TAYLOR_SMOOTH_RATE = 2; ///< at least this at the smallest resolved steps: smooth
constexpr double TAYLOR_NONSMOOTH_RATE = 1.5; ///< at most this there: a kink or a jump
/// Above this between larger steps (twice the smooth 3): the larger step crossed a jump or kink.
constexpr double TAYLOR_CROSSING_RATE = 6;
/// Remainders below this times max(|f(x)|, 1e-300) are round-off (the forward solves' tolerance);
/// a remainder, or R(h) - 4 R(h/2), is resolved where it exceeds 100 times it.
constexpr double TAYLOR_FLOOR = 1e-10;
/// At most this many halvings more where the rate at the smallest steps is out of line with the
/// one before it (TaylorCheck::settle_rates): the verdict waits for two that agree.
constexpr int TAYLOR_EXTRA_HALVINGS = 3;
/// Of problem.max_valid_step() taken as the first step, as the optimizers do.
constexpr double TAYLOR_VALID_FRACTION = 0.99;

struct TaylorCheck {
    VectorXd direction; ///< n: d (zero in a variable held by its bounds)
    double slope = 0; ///< g.d at x
    /// h, halvings + 1 of them (up to TAYLOR_EXTRA_HALVINGS more, fewer when stopped); the first
    /// is settings.step, or less where problem.max_valid_step() cuts it
    std::vector<double> steps;
    std::vector<double> changes; ///< |f(x + h d) - f(x)| (NaN where the point was rejected)
    std::vector<double> remainders; ///< signed R(h) = f(x + h d) - f(x) - h g.d (NaN where rejected)
    std::vector<double> rates; ///< log2(|R(2h)| / |R(h)|) from the second step on (NaN: unresolved)
    /// log2(|R(4h) - 4 R(2h)| / |R(2h) - 4 R(h)|) from the third step on (NaN: unresolved),
    /// the rate the verdict reads
    std::vector<double> settle_rates;
    double floor = 0; ///< TAYLOR_FLOOR max(|f(x)|, 1e-300)
    std::string verdict; ///< "smooth", "non_smooth" or "inconclusive"
    std::string reason; ///< the verdict in words
    int evaluations = 0, rejected = 0;
    bool stopped = false; ///< `stop` returned true: the steps after it were not evaluated
};

/// @brief The Taylor test at x along a random direction, uniform in [-1, 1] times `scales` per
/// variable, turned or zeroed where the first step would leave the bounds; the first step is
/// cut to TAYLOR_VALID_FRACTION of problem.max_valid_step() where that is below 1.
/// @param x, values  the point and f, g there (n entries)
/// @param lower, upper  n bounds (+-inf for a free side)
/// @param scales  n typical magnitudes of the variables (>= 0; 0 holds one), as diffipc gradcheck's
/// @param stop  asked before each evaluation; true ends the test (verdict inconclusive)
/// @throws InputError naming "optimizer.final_taylor_check" for a step <= 0 or halvings < 1
/// @throws std::invalid_argument for scales of the wrong size, negative or not finite
TaylorCheck final_taylor_check(OptimizationProblem& problem, const VectorXd& x, const OptimizationValues& values,
    const VectorXd& lower, const VectorXd& upper, const VectorXd& scales, const TaylorCheckSettings& settings,
    const std::function<bool()>& stop = {});

} // namespace diffipc
