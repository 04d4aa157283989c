#pragma once
/// @file friction_adjoint.hpp
/// The friction part of a step's adjoint: D_k depends on x_{k-1} through the
/// start-of-step positions and the data lagged there, and on the coefficients.

#include "forward/simulation/simulator.hpp"

namespace diffipc {

struct FrictionAdjointTerms {
    VectorXd* previous_positions = nullptr; ///< dJ/dx_{k-1} (#V*dim), accumulated
    VectorXd* coefficients = nullptr; ///< dJ/dmu per contact group, accumulated (null: not requested)
    VectorXd* rest_positions = nullptr; ///< dJ/dX (#V*dim), accumulated (null: not requested)
};

/// @brief Adds -lambda^T d(w grad D_k)/d(x_{k-1}, mu, X) to `terms`: through the
/// start-of-step positions, the normal forces, normals and closest-point weights
/// lagged at x_{k-1} (docs/math.md "Friction adjoint"), the pair coefficients, and
/// the edge-edge mollifier thresholds in the normal forces.
/// @param lambda  the step's adjoint (#V*dim, zero on constrained dofs)
/// @param weight  the integrator's weight w of the potentials in g_k
/// Call it for every step of a scene with friction (also one without lagged
/// contacts): with coefficients requested it checks the contacts at x_{k-1}.
/// @throws AdjointError if coefficients are requested and a group with coefficient 0
///         is in contact at x_{k-1}.
void friction_step_adjoint(
    const Simulator& sim, int k, const VectorXd& lambda, double weight, const FrictionAdjointTerms& terms);

} // namespace diffipc
