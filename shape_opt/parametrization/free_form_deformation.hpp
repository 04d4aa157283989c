#pragma once
/// @file free_form_deformation.hpp
/// Mesh-independent shape controls (docs/parametrizations.md): a free-form deformation
/// (Sederberg and Parry 1986) over an axis-aligned box. The design variables are the
/// displacements of a lattice of (n_1 + 1) x ... x (n_d + 1) control points along the active
/// axes; a rest vertex X inside the box, at local coordinates s = (X - lo) / (hi - lo) in
/// [0, 1]^d, moves by
///
///   u(X) = sum_{i,j,k} B_i^{n_1}(s_1) B_j^{n_2}(s_2) B_k^{n_3}(s_3) P_ijk,
///
/// B the Bernstein polynomials; vertices outside the box stay. The parameter vector depends
/// on the lattice only, not on the mesh: after a remesh the same x moves the new mesh the
/// same way, so an optimizer keeps its history. The outer layer of control points moves the
/// box's faces; fix it (`fixed_border`) for a deformation that is continuous across them, or
/// fix the faces normal to some axes only, where the body crosses the box there.
/// The output is the full rest-position vector X0 + u (#V * dim, vertex-major); linear in x.
/// With `mesh_at` the mesh given is the shape at those values instead of at 0.

#include "forward/mesh/mesh.hpp"
#include "shape_opt/parametrization/parameter_map.hpp"

namespace diffipc {

struct FfdLattice {
    VectorXd lower, upper; ///< dim corners of the box (m), upper > lower
    VectorXi degree; ///< dim polynomial degrees n_a >= 1 (n_a + 1 control points per axis)
    std::vector<int> axes; ///< active axes of the displacements
    /// Only the interior control points are variables (the box's faces stay in place).
    bool fixed_border = false;
    /// The same along some axes only: the control points on the box's faces normal to these
    /// axes stay (with fixed_border, all axes).
    std::vector<int> fixed_border_axes;
    /// The given mesh is the shape at these variable values (one per variable; empty: at 0):
    /// the rest positions are X(x) = Y0 + B(Y0) x with Y0 the positions that mesh_at moves onto
    /// the given mesh (pull_back). A remesh writes the new mesh at the current design with it.
    VectorXd mesh_at;
};

class FreeFormDeformation : public ParameterMap, public RemeshableShape {
public:
    /// @param rest #V by dim rest positions
    /// @throws InputError naming `field` for a box with upper <= lower, a degree below 1 or
    ///         above 20, bad axes, or a fixed border with no interior control point
    FreeFormDeformation(const Positions& rest, const FfdLattice& lattice, const std::string& field);
    Index in_size() const override { return m_basis.cols(); }
    Index out_size() const override { return m_rest.size(); }
    VectorXd apply(const VectorXd& x) const override;
    VectorXd vjp(const VectorXd& x, const VectorXd& y_bar) const override;
    std::string name() const override { return "ffd"; }
    /// The lattice and the shape it gives are the mesh's domain's, not its vertices'.
    bool input_survives_remesh() const override { return true; }
    const RemeshableShape* remeshable_shape() const override { return this; }
    std::string mesh_input_key() const override { return "mesh_at"; }
    /// Number of control points that are variables, and the position (m) of control point c
    /// (lattice order: axis 0 fastest).
    Index variable_points() const { return Index(m_points.size()); }
    VectorXd control_point(Index c) const;
    /// @brief The rest positions that the design x moves onto `current`: per row y, the X
    /// with X + u_x(X) = y (Newton's method on the lattice's polynomial; u = 0 outside the
    /// box). A remesh of the domain at x uses it to find the new mesh's rest positions, so
    /// that the same x gives the same domain (shape_opt/remesh.hpp).
    /// @throws std::runtime_error naming the vertex where the deformation cannot be inverted
    Positions pull_back(const Positions& current, const VectorXd& x) const override;

private:
    /// u_x(X) and du/dX (dim by dim) at any point X.
    void displacement(const VectorXd& X, const MatrixXd& control, VectorXd& u, MatrixXd& du) const;

    FfdLattice m_lattice;
    int m_dim;
    VectorXd m_rest;
    std::vector<Index> m_points; ///< lattice indices of the variable control points
    Index m_lattice_points = 0; ///< all of them, fixed ones included
    SparseMatrixd m_basis; ///< #V * dim by variable_points * |axes|: dy/dx
};

} // namespace diffipc
