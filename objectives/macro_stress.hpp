#pragma once
/// @file macro_stress.hpp
/// A periodic cell's homogenized stress (scene "periodic"; docs/math.md, "Periodic cells"): one
/// component of the cell-average first Piola stress of the elastic energy and the barrier across
/// the cell's boundary, per state.

#include "objectives/state_functional.hpp"

#include <string>

namespace diffipc {

/// @brief f(x_k) = P_ij = (1/|Y|) \sum_v (\nabla E(x_k))_{v,i} (X_v - X_o)_j (Pa), E = \Psi + \kappa B: the
/// derivative of the cell's elastic and barrier energy in G_ij over the box's volume, which at a
/// static equilibrium is the macro reaction of that component (zero in G's free components).
/// Written as s^T \nabla E with the lever vector s (s_{v,i} = (X_v - X_o)_j / |Y|): df/dx = H_E s,
/// the explicit partials d/d(mu, lambda) of s^T \nabla \Psi, and d/dX at fixed x (the lever's and
/// the potentials' shape derivatives).
class MacroStress : public StateFunctional {
public:
    MacroStress(int i, int j, int dim);
    std::string name() const override;
    double value(const Simulator& sim, const StateRef& state) const override;
    void add_gradient(const Simulator& sim, const StateRef& state, const ParameterRequest& request, double scale,
        VectorXd& d_positions, VectorXd& d_velocities, ParameterGradient& partials) const override;

private:
    /// The lever vector s of component (i, j) (std::logic_error if the scene is not periodic).
    VectorXd lever(const Simulator& sim) const;
    int m_i, m_j, m_dim;
};

} // namespace diffipc
