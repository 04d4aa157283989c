#pragma once
/// @file cell_sdf.hpp
/// The solid of a microstructure cell (issue 15; docs/math.md, "Microstructure cells"): the
/// smooth union of thick edges of a wire graph, periodic with the cell [-1, 1]^2,
///
///     phi(x; p) = -k log sum_(e, s) exp(-d_e(x - 2 s) / k),   d_e(y) = |y - c_e(y)| - w_e / 2,
///
/// over the edges e and the lattice shifts s in {-1, 0, 1}^2 (the neighbouring cells' edges; x is
/// first moved into the cell by whole periods, so phi is exactly periodic, and edges two cells
/// away, at least a cell width off, would add less than exp(-1/k) to the sum), with
/// c_e(y) the point of edge e (between its nodes' moved positions n_a + u_a, n_b + u_b) nearest y,
/// w_e the edge's thickness and k > 0 the blending radius (k -> 0: the plain union, the minimum of
/// the d_e; the smooth union lies below it by at most k log(#terms)). The solid is phi < 0.
/// phi is smooth in x and in every parameter wherever the nearest points c_e are (the segments'
/// clamped projections are, away from the perpendiculars through their endpoints, where d_e is
/// still C^1).

#include "shape_opt/microstructure/wire_graph.hpp"

namespace diffipc {

/// The parameters of a cell, flattened as [u (2 #N, node-major), w (#M), k].
struct CellParameters {
    MatrixXd offsets; ///< #N by 2 node displacements u
    VectorXd thickness; ///< #M edge thicknesses w (> 0)
    double blend = 0.05; ///< k (> 0)

    /// [u row-major, w, k]
    VectorXd flatten() const;
    /// The inverse of flatten() for a graph with n nodes and m edges.
    static CellParameters unflatten(const VectorXd& p, Index n, Index m);
};

class CellSDF {
public:
    CellSDF(WireGraph graph, CellParameters parameters);

    const WireGraph& graph() const { return m_graph; }
    const CellParameters& parameters() const { return m_p; }

    double value(const Eigen::Vector2d& x) const;
    /// d phi / dx.
    Eigen::Vector2d gradient(const Eigen::Vector2d& x) const;
    /// d phi / dp in the order of CellParameters::flatten.
    VectorXd parameter_gradient(const Eigen::Vector2d& x) const;

private:
    /// phi at x, and if asked its x-gradient and parameter gradient.
    double evaluate(const Eigen::Vector2d& x, Eigen::Vector2d* dx, VectorXd* dp) const;

    WireGraph m_graph;
    CellParameters m_p;
};

} // namespace diffipc
