#pragma once
/// @file friction_adjoint.hpp
/// The friction part of a step's adjoint: D_k depends on x_{k-1} through the
/// start-of-step positions and the data lagged there, and on the coefficients.

#include "forward/simulation/simulator.hpp"

namespace diffipc {

struct FrictionAdjointTerms {
    VectorXd* previous_positions = nullptr; ///< dJ/dx_{k-1} (#V*dim), accumulated
    VectorXd* coefficients = nullptr; ///< dJ/dmu per contact group, accumulated (null: not requested)
};

/// @brief Adds -lambda^T d(w grad D_k)/d(x_{k-1}, mu) to `terms`.
/// @throws AdjointError while the lagged data's own dependence is not differentiated.
void friction_step_adjoint(
    const Simulator& sim, int k, const VectorXd& lambda, double weight, const FrictionAdjointTerms& terms);

} // namespace diffipc
