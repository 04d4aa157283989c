#pragma once
/// @file macro_gradient.hpp
/// A periodic cell's macroscopic displacement gradient G (scene "periodic"; docs/math.md,
/// "Periodic cells") as a per-state functional: one component, prescribed or free. Cushion
/// designs penalize a cell's shear (G_xy, G_yx) and lateral expansion (G_xx) under compression.

#include "objectives/state_functional.hpp"

namespace diffipc {

/// @brief f(x_k) = G_ij = (x_b - x_a)_i / (X_b - X_a)_j - delta_ij, with a, b two vertices of one
/// class a lattice step apart along axis j (the deformed cell tiles space: x_b - x_a = (I + G)
/// (X_b - X_a)). df/dx has two entries; at fixed x, the rest length (X_b - X_a)_j moves with X.
class MacroGradient : public StateFunctional {
public:
    MacroGradient(int i, int j, int dim);
    std::string name() const override;
    double value(const Simulator& sim, const StateRef& state) const override;
    void add_gradient(const Simulator& sim, const StateRef& state, const ParameterRequest& request, double scale,
        VectorXd& d_positions, VectorXd& d_velocities, ParameterGradient& partials) const override;

private:
    /// The pair (a, b) along axis j (std::logic_error if the scene is not periodic along j).
    std::pair<Index, Index> pair(const Simulator& sim) const;
    int m_i, m_j, m_dim;
};

} // namespace diffipc
