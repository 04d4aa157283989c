#pragma once
/// @file markers.hpp
/// Positions of marker points over time against target data (e.g. tracked
/// points of an experiment), for fitting material or initial-condition parameters.

#include "objectives/objective.hpp"

#include <vector>

namespace diffipc {

/// A point that moves with the mesh: p(x) = \sum_i w_i x_{v_i}.
struct MarkerPoint {
    std::vector<Index> vertices;
    std::vector<double> weights; ///< one per vertex; fixed (no parameter dependence)

    /// @brief The vertex v itself.
    static MarkerPoint vertex(Index v) { return { { v }, { 1.0 } }; }
    /// @brief The point of element e with barycentric coordinates `weights` (dim+1 numbers summing to 1).
    /// @throws std::invalid_argument for a wrong count or a sum off 1 by more than 1e-12 relative.
    static MarkerPoint barycentric(const Mesh& mesh, Index e, const std::vector<double>& weights);
};

/// @brief J = \sum_{k \in K} \sum_{m=1}^{M} \tfrac{w_m}{2} |p_m(x_k) - y_{m,k}|^2 (m^2 times the
/// weights' unit) over the listed states K.
///
/// dJ/dx_k: w_m (p_m(x_k) - y_{m,k}) spread to the marker's vertices with its weights. The
/// barycentric weights are fixed, so there is no explicit parameter partial (a marker follows the
/// material point, whatever the rest shape); no velocity dependence.
class MarkerTracking : public Objective {
public:
    /// @param markers the M marker points
    /// @param steps   the states k compared (0 = initial state, 1..T the steps)
    /// @param targets one M by dim matrix of target positions y_{m,k} (m), row per marker, per listed state
    /// @param weights M marker weights w_m >= 0 (empty: all 1)
    /// @throws std::invalid_argument for inconsistent sizes
    MarkerTracking(std::vector<MarkerPoint> markers, std::vector<int> steps, std::vector<Positions> targets,
        VectorXd weights = {});

    std::string name() const override { return "markers"; }
    /// @throws std::out_of_range if a listed state is beyond the trajectory.
    double value(const Simulator& sim, const Trajectory& trajectory) const override;
    void add_gradient(const Simulator& sim, const Trajectory& trajectory, const ParameterRequest& request, double scale,
        StateSeed& seed) const override;
    /// The listed states.
    std::vector<int> states_read(int) const override { return m_steps; }

    /// @brief M by dim marker positions p_m(x) for flattened positions x.
    Positions positions(const VectorXd& x, int dim) const;

private:
    /// p(x_k) - y_k for the s-th listed state.
    Positions residual(const Trajectory& trajectory, size_t s, int dim) const;

    std::vector<MarkerPoint> m_markers;
    std::vector<int> m_steps;
    std::vector<Positions> m_targets;
    VectorXd m_weights;
};

} // namespace diffipc
