#pragma once
/// @file boundary_extension.hpp
/// Shape design by boundary displacements (docs/parametrizations.md): the design variables
/// are displacements of selected boundary vertices along active axes; every other boundary
/// vertex stays, and the interior follows by the harmonic extension
///
///   L_II u_I = -L_IB u_B   (per axis, L the P1 Laplacian of the rest mesh),
///
/// so that moving the boundary does not drag single interior vertices across their
/// neighbours. The output is the full rest-position vector X0 + u (#V * dim, vertex-major),
/// the layout of a "shape" parameter over every vertex. Linear in x: the VJP is E^T y_bar
/// with one solve by the factored L_II.

#include "forward/mesh/mesh.hpp"
#include "shape_opt/parametrization/parameter_map.hpp"

#include <memory>

namespace diffipc {

class BoundaryExtension : public ParameterMap {
public:
    /// @param mesh the rest mesh (every body)
    /// @param vertices the design vertices: boundary vertices, each listed once
    /// @param axes active axes (each in [0, dim), listed once); x holds, per design vertex in
    ///        order, its displacement along each active axis
    /// @throws InputError naming `field` for a vertex out of range, not on the boundary or
    ///         listed twice, or a bad axis
    BoundaryExtension(
        const Mesh& mesh, const std::vector<Index>& vertices, const std::vector<int>& axes, const std::string& field);
    ~BoundaryExtension() override;
    Index in_size() const override { return Index(m_vertices.size() * m_axes.size()); }
    Index out_size() const override { return m_rest.size(); }
    VectorXd apply(const VectorXd& x) const override;
    VectorXd vjp(const VectorXd& x, const VectorXd& y_bar) const override;
    bool invertible() const override { return true; }
    /// The design vertices' displacements from rest (the other entries of y are not checked
    /// against the extension: an initial design is the rest mesh moved at those vertices).
    VectorXd inverse(const VectorXd& y, const std::string& field) const override;
    std::string name() const override { return "boundary_extension"; }

private:
    struct Solver;
    int m_dim;
    VectorXd m_rest; ///< X0, flattened
    std::vector<Index> m_vertices;
    std::vector<int> m_axes;
    std::vector<Index> m_interior; ///< vertices not on the boundary
    std::vector<Index> m_interior_slot; ///< per vertex: its row in L_II, or -1
    SparseMatrixd m_L_IB; ///< interior rows, boundary-vertex columns (all vertices' numbering)
    std::unique_ptr<Solver> m_solver; ///< L_II factored
};

} // namespace diffipc
