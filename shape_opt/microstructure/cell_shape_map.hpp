#pragma once
/// @file cell_shape_map.hpp
/// How a cell's mesh moves with its family's design variables (issue 15; docs/microstructures.md,
/// "Shape derivative"): the rest-position velocity V = dX/dp of a mesh of the design p, with
/// which the adjoint's shape gradient becomes the design gradient, dJ/dp = V^T dJ/dX.
///
/// With psi(X) = phi(y(X); p) the solid's level set in physical coordinates (y = X scaled back
/// into the graph's [-1, 1]^2 at width a, cell_mesher.hpp), for a variable p_j other than the width:
///   - a boundary vertex inside the box moves along the normal n = grad psi / |grad psi| with the
///     level set's normal velocity, V = -(d psi / d p_j) / |grad psi| n;
///   - a boundary vertex where the contour meets a side of the box slides along the side (tangent
///     t) so as to stay on psi = 0, V = -(d psi / d p_j) / (grad psi . t) t; the box's corners stay;
///     the vertices of a side between two such ends follow them linearly in their distance along
///     the side (opposite sides alike, so the mesh stays periodic);
///   - the interior follows by the harmonic extension of the boundary's velocity
///     (L_II V_I = -L_IB V_B per axis, L the P1 Laplacian of the mesh; boundary_extension.hpp).
/// The width stretches the whole mesh along x: V = (X_x / a, 0).
///
/// moved(q) is a mesh of design q that moves this way: boundary vertices inside the box are put
/// on psi_q = 0 along their fixed normal n, the sides' crossings along their side, the sides'
/// other vertices linearly between them, the interior by the same harmonic extension of the
/// boundary's displacement, and the whole then stretched by a_q / a_p along x. It is smooth in
/// q and its derivative at q = p is V, which is what the finite-difference checks of the whole
/// pipeline compare against.

#include "forward/mesh/mesh.hpp"
#include "shape_opt/microstructure/cell_family.hpp"

#include <memory>

namespace diffipc {

class BoundaryExtension;

class CellShapeMap {
public:
    /// @param mesh a mesh of the family's design p (mesh_cell at `height`)
    CellShapeMap(const CellFamily& family, const VectorXd& p, const Mesh& mesh, double height);
    ~CellShapeMap();

    /// dX/dp: #V*2 (vertex-major) by the family's size.
    const MatrixXd& velocity() const { return m_velocity; }
    /// dJ/dp = V^T dJ/dX.
    VectorXd pullback(const VectorXd& dJ_dX) const { return m_velocity.transpose() * dJ_dX; }
    /// The mesh's rest positions moved to design q (#V by 2; see the file's comment).
    /// @throws InputError naming "design" if a boundary vertex finds no level set to move to
    Positions moved(const VectorXd& q) const;

    /// d moved(q) / dq (#V*2 by the family's size): at q = p the velocity(); elsewhere the
    /// boundary vertices' d t / dq = -(d psi_q / dq) / (grad psi_q . n) at their moved positions,
    /// the same extension, and the stretch.
    MatrixXd moved_jacobian(const VectorXd& q) const;

    /// Per vertex: 0 interior, 1 on the contour inside the box, 2 a side's crossing, 3 a box
    /// corner, 4 on a side between its ends (for tests and plots).
    const std::vector<int>& kind() const { return m_kind; }

private:
    /// psi and its X-gradient at physical X for the design's cell parameters c (width a_p).
    double psi(const CellSDF& sdf, const Eigen::Vector2d& X, Eigen::Vector2d* grad) const;
    /// Boundary vertices' displacement (nb by 2) for design q at the reference width; with
    /// `jacobian`, also its derivative in q (2 nb by the family's size, the width's column zero).
    MatrixXd boundary_displacement(const VectorXd& q, MatrixXd* jacobian = nullptr) const;

    const CellFamily& m_family;
    VectorXd m_p;
    Mesh m_mesh;
    double m_height;
    Eigen::Vector2d m_scale; ///< X = scale .* y at the design's width
    std::vector<int> m_kind;
    std::vector<Index> m_boundary; ///< the boundary vertices, in the extension's order
    std::vector<Eigen::Vector2d> m_direction; ///< per boundary vertex: n, t, or 0
    /// Per boundary vertex on a side between its ends: the two ends (boundary slots) and the weight of the second.
    struct Between {
        Index slot, a, b;
        double weight;
    };
    std::vector<Between> m_between;
    std::unique_ptr<BoundaryExtension> m_extension;
    MatrixXd m_velocity;
};

} // namespace diffipc
