#pragma once
/// @file gradient_check.hpp
/// The verdict of `diffipc gradcheck` on one direction (docs/problem_format.md, "gradcheck"):
/// the adjoint's directional derivative g.dp against finite differences of j(h) = J(p + h dp)
/// and the Taylor remainders |j(h) - j(0) - h g.dp|.
///
/// A central difference assumes j is smooth on both sides of 0. An exterior penalty
/// w max(0, c(p) - c_max)^2 at c(p) = c_max (a constraint active at the start) is only C^1:
/// j'' jumps at 0, and any central difference then has an O(h) error (the fourth-order one:
/// (j''(0+) - j''(0-)) h / 6), although the gradient is right. So when the central difference
/// disagrees, each side is differenced on its own, j'(0+-) ~ (j(+-h) - j(0)) / (+-h), and the
/// O(h) and O(h^2) terms of these one-sided quotients are removed by Richardson extrapolation
/// over h, h/2, h/4. Both sides agreeing with g.dp is a pass across a kink; sides that disagree
/// with each other mean that J is not differentiable at p along dp (nothing can be checked).

#include <functional>
#include <string>
#include <vector>

namespace diffipc {

enum class DirectionVerdict {
    PASS, ///< the central difference and the Taylor rate agree with the adjoint
    PASS_AT_KINK, ///< the central difference straddles a jump of j''; both one-sided slopes agree
    FAIL, ///< the differences disagree with the adjoint
    NOT_DIFFERENTIABLE, ///< the one-sided slopes differ from each other: no gradient to check
    INCONCLUSIVE, ///< j does not change above the solver floor: nothing was checked
};

/// "PASS", "PASS (kink)", "FAIL", "NOT DIFFERENTIABLE", "INCONCLUSIVE".
const char* verdict_name(DirectionVerdict verdict);

/// A verdict that counts as a checked, right gradient.
inline bool passed(DirectionVerdict verdict)
{
    return verdict == DirectionVerdict::PASS || verdict == DirectionVerdict::PASS_AT_KINK;
}

/// What the check measured along one direction.
struct DirectionCheck {
    struct TaylorRow {
        double h; ///< step
        double first; ///< |j(h) - j(0)|
        double second; ///< |j(h) - j(0) - h g.dp|
    };
    double slope = 0; ///< the adjoint's g.dp
    double central = 0; ///< fourth-order central difference at `step`
    double central_error = 0; ///< |slope - central| / max(|slope|, |central|)
    std::vector<TaylorRow> taylor; ///< h = step, step/2, ..., step/2^halvings
    double floor = 0; ///< the solver floor 1e-10 |j(0)|: remainders below it are noise
    double last_rate = 0; ///< the last rate of the second-order remainders above the floor
    int resolved = 0; ///< second-order remainders above the floor
    /// Only when the central difference disagreed: the one-sided slopes j'(0+) and j'(0-),
    /// Richardson-extrapolated, and their relative errors against `slope`.
    bool one_sided = false;
    double forward = 0, backward = 0;
    double forward_error = 0, backward_error = 0;
    DirectionVerdict verdict = DirectionVerdict::FAIL;
};

/// Relative error tolerance of a difference against the adjoint.
inline constexpr double GRADIENT_CHECK_TOLERANCE = 1e-5;
/// One-sided slopes further apart than this (relative) mean a kink of j itself.
inline constexpr double KINK_SLOPE_GAP = 1e-3;

/// @brief Judges one direction.
/// @param j j(h) = J(p + h dp) (called with each step at most once)
/// @param j0 j(0)
/// @param slope the adjoint's g.dp
/// @param step the first step (the central difference's and the Taylor table's)
/// @param halvings the Taylor table has steps step / 2^i, i = 0..halvings; the one-sided
///        differences use at least i = 0..2
DirectionCheck check_direction(
    const std::function<double(double)>& j, double j0, double slope, double step, int halvings);

/// Richardson extrapolation of one-sided quotients D(h_i), h_i = h_0 / 2^i, whose error is
/// c_1 h + c_2 h^2 + O(h^3): the second-level estimate of the three consecutive steps whose
/// estimate changed least from the first level (the least affected by round-off and by a kink
/// that the coarser steps reach). At least three quotients.
double richardson_one_sided(const std::vector<double>& quotients);

} // namespace diffipc
