#pragma once
/// @file center_of_mass.hpp
/// Centre-of-mass trajectory against target data.

#include "objectives/objective.hpp"

#include <vector>

namespace diffipc {

/// @brief J = \tfrac{w}{2} \sum_{k \in K} |c(x_k) - y_k|^2 (m^2 times w's unit) with the
/// mass-weighted centre c(x) = \sum_v m_v x_v / \sum_v m_v of the chosen elements, lumped masses
/// m_v = \sum_{e \ni v} \rho_e |e| / (d+1) (the consistent mass matrix has the same row sums, so
/// the centre is the same). Equivalently c = \sum_e m_e \bar x_e / \sum_e m_e with element
/// masses m_e = \rho_e |e| and centroids \bar x_e.
///
/// dJ/dx_a = \sum_{e \ni a} g m_e / ((d+1) M) with g = w (c - y_k) and M = \sum_e m_e. Explicit
/// partials through the masses: dc/dm_e = (\bar x_e - c) / M, dm_e/d\rho_e = |e|,
/// dm_e/dX_a = \rho_e |e| G_a. No velocity or Lame dependence.
class CenterOfMassTracking : public Objective {
public:
    /// @param steps   the states k compared (0 = initial state, 1..T the steps)
    /// @param targets #steps by dim target centres y_k (m), row per listed state
    /// @param weight  w
    /// @param elements the elements whose mass counts (a body); empty: all
    /// @throws std::invalid_argument for inconsistent sizes
    CenterOfMassTracking(
        std::vector<int> steps, Positions targets, double weight = 1.0, std::vector<Index> elements = {});

    std::string name() const override { return "center_of_mass"; }
    /// @throws std::out_of_range if a listed state is beyond the trajectory.
    double value(const Simulator& sim, const Trajectory& trajectory) const override;
    void add_gradient(const Simulator& sim, const Trajectory& trajectory, const ParameterRequest& request, double scale,
        StateSeed& seed) const override;
    /// The listed states.
    std::vector<int> states_read(int) const override { return m_steps; }

    /// @brief The centre of mass c(x) (dim) of flattened positions x.
    VectorXd center(const Simulator& sim, const VectorXd& x) const;

private:
    std::vector<int> m_steps;
    Positions m_targets;
    double m_weight;
    std::vector<Index> m_elements;
};

} // namespace diffipc
