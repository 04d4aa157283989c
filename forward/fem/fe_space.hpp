#pragma once
/// @file fe_space.hpp
/// P1 finite-element space on a simplicial mesh: rest volumes and constant
/// shape-function gradients per element, deformation gradients, masses.

#include "forward/common/types.hpp"
#include "forward/mesh/mesh.hpp"

#include <vector>

namespace diffipc {

class FESpace {
public:
    explicit FESpace(const Mesh& mesh);

    int dim() const { return m_dim; }
    Index num_elements() const { return Index(m_volumes.size()); }
    const Mesh& mesh() const { return m_mesh; }
    /// Rest volume (area in 2D) of element e.
    double rest_volume(Index e) const { return m_volumes[size_t(e)]; }
    const std::vector<double>& rest_volumes() const { return m_volumes; }
    /// (dim+1) by dim matrix G with G(a, j) = dN_a/dX_j, stored row-major.
    const double* shape_gradients(Index e) const
    {
        return m_gradients.data() + size_t(e) * size_t((m_dim + 1) * m_dim);
    }

    /// @brief Deformation gradient F = sum_a x_a G_a^T of element e (dim by dim, row-major output).
    /// @param x flattened deformed positions
    void deformation_gradient(Index e, const VectorXd& x, double* F) const;

    /// @brief Lumped (row-sum) nodal masses: rho |e| / (dim+1) per element vertex.
    /// @param density #E element densities (kg/m^3)
    VectorXd lumped_masses(const VectorXd& density) const;
    /// @brief Consistent mass matrix on dofs (#V*dim square, full storage):
    /// M_e = rho |e| / ((d+1)(d+2)) (1 + delta_ab) per component.
    SparseMatrixd consistent_mass(const VectorXd& density) const;

    /// @brief Minimum over elements of current volume / rest volume.
    double min_volume_ratio(const VectorXd& x) const;

private:
    const Mesh& m_mesh;
    int m_dim;
    std::vector<double> m_volumes;
    std::vector<double> m_gradients;
};

/// @brief Largest t in (0, 1] such that every element of x + s p keeps a
/// volume above `keep` times its volume at x for all s in [0, t]. The volume
/// along the line is a polynomial in s (quadratic in 2D, cubic in 3D); its
/// first crossing is bracketed between critical points and bisected, and the
/// returned t is verified by evaluating the polynomial.
/// @param x, p flattened positions and search direction
double inversion_free_step(const Mesh& mesh, const VectorXd& x, const VectorXd& p, double keep = 0.1);

/// @brief Coefficients c0..c3 of det[Ds(x + t p)] (scaled volume) of element e.
Eigen::Vector4d volume_polynomial(const Mesh& mesh, Index e, const VectorXd& x, const VectorXd& p);

} // namespace diffipc
