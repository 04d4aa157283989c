#pragma once
/// @file reaction_force.hpp
/// The force a prescribed boundary (a Dirichlet condition, or an obstacle) exerts on the
/// bodies, along one axis: what a load cell under a plate measures.

#include "objectives/objective.hpp"
#include "objectives/state_functional.hpp"

#include <string>
#include <vector>

namespace diffipc {

/// @brief f(x_k) = R_k = \sum_{i \in S} (\nabla \Psi(x_k) + \nabla B(x_k) - f_{ext}(t_k))_i (N): the
/// sum over the dofs S that one Dirichlet condition (or one obstacle) prescribes along one axis.
/// At a static equilibrium the free rows of this gradient vanish and its prescribed rows are the
/// forces the supports exert on the bodies, so R_k is the force of that boundary on the bodies
/// along the axis (negative when it pushes them toward -axis); for an obstacle it is the contact
/// force the obstacle exerts. In a dynamic scene it is the force transmitted through the elements
/// and contacts, without the inertia of the prescribed vertices' own (lumped) mass.
///
/// dR/dx_k = (H_\Psi + H_B) s with s the indicator vector of S (the true Hessians). Explicit
/// partials: d/d(mu, lambda) and d/dX of s^T \nabla \Psi, d/dX of s^T \nabla B (the edge-edge
/// mollifier thresholds), and -d(s^T f_{ext})/dX, -d(s^T f_{ext})/d\rho (gravity through the lumped
/// masses, tractions through facet areas). No velocity dependence. Scenes with friction are
/// refused (std::logic_error; parse_objective() names the field): the friction force depends on
/// the previous state and the lagged data.
class ReactionForce : public StateFunctional {
public:
    /// @param dofs  the dofs S (each along the same axis)
    /// @param label for name(), e.g. "dirichlet[1].z"
    ReactionForce(std::vector<Index> dofs, std::string label);

    std::string name() const override { return "reaction_force(" + m_label + ")"; }
    double value(const Simulator& sim, const StateRef& state) const override;
    void add_gradient(const Simulator& sim, const StateRef& state, const ParameterRequest& request, double scale,
        VectorXd& d_positions, VectorXd& d_velocities, ParameterGradient& partials) const override;

    const std::vector<Index>& dofs() const { return m_dofs; }

private:
    std::vector<Index> m_dofs;
    std::string m_label;
};

/// @brief The dofs that condition `condition` prescribes along `axis`: a Dirichlet condition's
/// index in scene.dirichlet, or dirichlet.size() + o for obstacle o (Simulator::prescribing_condition()).
/// Empty if it prescribes none along that axis.
std::vector<Index> prescribed_dofs_of(const Simulator& sim, int condition, int axis);

} // namespace diffipc
