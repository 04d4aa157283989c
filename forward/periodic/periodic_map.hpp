#pragma once
/// @file periodic_map.hpp
/// The unknowns of a periodic cell (issue 14; docs/math.md, "Periodic cells") and the linear map
/// from them to the mesh's positions:
///
///     x_v = X_v + G (X_v - X_o) + w_c(v),
///
/// w_c the periodic fluctuation of vertex class c (forward/periodic/pairing.hpp), G the d x d
/// macroscopic displacement gradient, X_o an origin (the box's lower corner: G's entries then do
/// not depend on where the cell lies). Reduced unknowns q = [w_0 .. w_{C-1}, L G row-major], L a
/// length (the box's longest edge: q's macro entries are lengths like the others, and their
/// residual rows forces), and x = X + P q with P sparse (#V d by C d + d^2). Two vertices of a class then differ by
/// (I + G) times their lattice offset: the deformed cell tiles space. On a non-periodic axis
/// a, G's column a multiplies X_a and w carries the displacement (no constraint across it).

#include "forward/common/types.hpp"
#include "forward/periodic/pairing.hpp"

namespace diffipc {

class PeriodicMap {
public:
    /// @param mesh the cell's mesh (its rest positions X)
    /// @param pairing its vertex classes
    /// @param origin X_o (empty: 0); @param length L (> 0)
    PeriodicMap(const Mesh& mesh, const PeriodicPairing& pairing, const VectorXd& origin = {}, double length = 1);

    int dim() const { return m_dim; }
    Index num_classes() const { return m_classes; }
    /// C d + d^2
    Index num_reduced() const { return m_classes * m_dim + m_dim * m_dim; }
    /// Index in q of the fluctuation component i of class c.
    Index fluctuation_dof(Index c, int i) const { return c * m_dim + i; }
    /// Index in q of L G(i, j).
    Index macro_dof(int i, int j) const { return m_classes * m_dim + i * m_dim + j; }

    /// P (#V d by num_reduced()).
    const SparseMatrixd& matrix() const { return m_P; }
    /// X + P q.
    VectorXd positions(const VectorXd& q) const;
    /// The q of positions x = X + P q whose macro gradient is G (d x d row-major, d^2 values):
    /// each class's fluctuation read at its representative.
    VectorXd reduced(const VectorXd& x, const VectorXd& G) const;
    /// G (d^2 values, row-major) of q.
    VectorXd macro_gradient(const VectorXd& q) const { return q.tail(m_dim * m_dim) / m_length; }
    /// dE/dG (d^2 values, row-major) of a full-space gradient g = dE/dx: sum_v g_v (X_v - X_o)^T.
    VectorXd macro_derivative(const VectorXd& g) const { return m_length * reduce(g).tail(m_dim * m_dim); }
    double length() const { return m_length; }
    /// X_o.
    const VectorXd& origin() const { return m_origin; }
    /// P q.
    VectorXd expand(const VectorXd& q) const { return m_P * q; }
    /// P^T g: a full-space gradient (or any covector) in the reduced unknowns.
    VectorXd reduce(const VectorXd& g) const { return m_P.transpose() * g; }
    /// P^T H P of a symmetric full-space matrix given by its lower triangle; the lower triangle
    /// of the result.
    SparseMatrixd reduce_matrix(const SparseMatrixd& lower) const;

private:
    int m_dim;
    Index m_classes;
    VectorXd m_rest;
    SparseMatrixd m_P;
    VectorXi m_representative;
    VectorXd m_origin;
    double m_length = 1;
};

} // namespace diffipc
