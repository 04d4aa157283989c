#pragma once
/// @file compliance.hpp
/// Compliance (work of the external loads) of one state.

#include "objectives/state_functional.hpp"

namespace diffipc {

/// @brief f(x_k) = f_{ext}(t_k)^T (x_k - X) (J): the nodal external forces of the scene at the
/// state's time (gravity through the lumped masses, Neumann tractions; Simulator::external_forces)
/// dotted with the displacement u_k = x_k - X. Obstacle and Dirichlet dofs count like any other
/// (their external force is what the scene applies there; reactions are not included).
///
/// df/dx_k = f_{ext}(t_k). Explicit partials: df/dX = -f_{ext}(t_k) + d(u^T f_{ext}(t_k))/dX at
/// fixed u, and df/d\rho = d(u^T f_{ext}(t_k))/d\rho; the force's own dependence on the
/// parameters (masses m_v = \sum_e \rho_e |e| / (d+1), facet areas) comes from
/// Simulator::external_force_derivatives. Traction expressions are evaluated at the scene's rest
/// facet centroids (forward/simulation/parameters.hpp), so a shape change moves the loaded
/// areas but not where the expressions are sampled. No velocity or Lame dependence.
class Compliance : public StateFunctional {
public:
    std::string name() const override { return "compliance"; }
    double value(const Simulator& sim, const StateRef& state) const override;
    void add_gradient(const Simulator& sim, const StateRef& state, const ParameterRequest& request, double scale,
        VectorXd& d_positions, VectorXd& d_velocities, ParameterGradient& partials) const override;
};

} // namespace diffipc
