#pragma once
/// @file kinetic_energy.hpp
/// Kinetic energy of one state.

#include "objectives/state_functional.hpp"

#include <vector>

namespace diffipc {

/// @brief f(v) = \tfrac12 v^T M v (J) with the scene's mass matrix (lumped or consistent,
/// Simulator::inertia()), assembled from the chosen elements:
/// lumped  K_e = \frac{\rho_e |e|}{2(d+1)} \sum_{a \in e} |v_a|^2,
/// consistent  K_e = \frac{\rho_e |e|}{2(d+1)(d+2)} (|\sum_{a \in e} v_a|^2 + \sum_{a \in e} |v_a|^2).
///
/// df/dv = M v; explicit partials through the masses: df/d\rho_e = K_e / \rho_e and
/// df/dX_a = \sum_{e \ni a} K_e G_a (from d|e|/dX_a = |e| G_a). No position or Lame dependence.
class KineticEnergy : public StateFunctional {
public:
    /// @param elements the elements whose mass counts (a body); empty: all
    explicit KineticEnergy(std::vector<Index> elements = {})
        : m_elements(std::move(elements))
    {
    }
    std::string name() const override { return "kinetic_energy"; }
    double value(const Simulator& sim, const StateRef& state) const override;
    void add_gradient(const Simulator& sim, const StateRef& state, const ParameterRequest& request, double scale,
        VectorXd& d_positions, VectorXd& d_velocities, ParameterGradient& partials) const override;

private:
    double evaluate(const Simulator& sim, const VectorXd& v, const ParameterRequest* request, double scale,
        VectorXd* dv, ParameterGradient* partials) const;
    std::vector<Index> m_elements;
};

} // namespace diffipc
