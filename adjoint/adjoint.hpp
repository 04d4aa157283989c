#pragma once
/// @file adjoint.hpp
/// The discrete adjoint of a recorded run (docs/math.md "Adjoint").
///
/// Step k solves g_k(x_k; x_{k-1}, x_{k-2}, v_{k-1}, ..., p) = 0 on the free dofs,
/// g_k the gradient of the incremental potential; prescribed dofs are
/// x_k = X + g_k. Backward from k = T: the state adjoints (dJ/dv_k, dJ/da_k)
/// are pushed into x_k and the history through the integrator's linear maps,
/// then H_k lambda_k = dJ/dx_k on the free dofs, H_k the true (unprojected)
/// Hessian at the converged state, and lambda_k carries the sensitivity to the
/// history (inertial target, start-of-step positions) and the parameters:
/// dJ/dp -= lambda_k^T dg_k/dp.

#include "adjoint/sensitivity.hpp"
#include "forward/simulation/simulator.hpp"

#include <stdexcept>
#include <string>

namespace diffipc {

/// A gradient that cannot be computed (failed forward step, unsupported
/// configuration, singular adjoint system); no number is returned.
class AdjointError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

/// Timings and sizes of one backward sweep.
struct AdjointStatistics {
    double assembly_time = 0; ///< Hessians and parameter derivatives (s)
    double factorization_time = 0; ///< s
    double solve_time = 0; ///< triangular solves (s)
    double total_time = 0; ///< s
    int steps = 0; ///< adjoint systems solved
};

/// @brief dJ/dp of an objective over the simulator's committed trajectory.
/// @param sim      a simulator whose run() committed every step of its scene
///                 (the potentials are reconfigured step by step; its trajectory is unchanged)
/// @param seed     dJ/dx_k, dJ/dv_k for k = 0..T and J's explicit partials
/// @param request  the parameter blocks to compute (nothing else is)
/// @param stats    optional timings
/// @throws AdjointError if the run failed or stopped early, if contact used the
///         adaptive barrier stiffness (differentiate with a fixed kappa), if a
///         friction step re-lagged within the step, or if an adjoint system is singular.
ParameterGradient adjoint_gradient(
    Simulator& sim, const StateSeed& seed, const ParameterRequest& request, AdjointStatistics* stats = nullptr);

} // namespace diffipc
