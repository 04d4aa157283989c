#pragma once
/// @file elastic_energy.hpp
/// Elastic energy of one state.

#include "objectives/state_functional.hpp"

#include <vector>

namespace diffipc {

/// @brief f(x) = \sum_e |e| \psi_e(F_e(x)) (J) over the chosen elements, each with its own
/// material law and Lame parameters (forward/potentials/elastic_potential.hpp).
///
/// df/dx_a = |e| P G_a; df/dX_a = |e| (\psi I - F^T P) G_a (the Eshelby form,
/// element_kinematics.hpp); df/d\mu_e = |e| \psi(F; 1, 0), df/d\lambda_e = |e| \psi(F; 0, 1),
/// since every law is linear in (\mu, \lambda). No velocity or density dependence.
class ElasticEnergy : public StateFunctional {
public:
    /// @param elements the elements summed over (a body); empty: all
    explicit ElasticEnergy(std::vector<Index> elements = {})
        : m_elements(std::move(elements))
    {
    }
    std::string name() const override { return "elastic_energy"; }
    double value(const Simulator& sim, const StateRef& state) const override;
    void add_gradient(const Simulator& sim, const StateRef& state, const ParameterRequest& request, double scale,
        VectorXd& d_positions, VectorXd& d_velocities, ParameterGradient& partials) const override;
    /// 64 eps sum_e |e| (mu_e + |lambda_e|) (1 + |F_e|^2): the size of the terms that cancel in
    /// psi (a rigidly moving body's energy comes out as -8e-17 J, not 0).
    double round_off(const Simulator& sim, const StateRef& state) const override;

private:
    std::vector<Index> m_elements;
};

} // namespace diffipc
