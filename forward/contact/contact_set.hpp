#pragma once
/// @file contact_set.hpp
/// Active contacts: primitive pairs closer than dmin + dhat, each with the
/// closest-feature type that realizes its distance. A committed step keeps its
/// set (the adjoint differentiates the barrier of exactly these pairs).

#include "forward/common/types.hpp"
#include "forward/kernels/contact_kind.hpp"

#include <array>
#include <cstdint>
#include <vector>

namespace diffipc {

// One enum for both paths (forward/kernels/contact_kind.hpp).
using kernels::ContactKind;

struct Contact {
    ContactKind kind = ContactKind::VERTEX_FACE;
    /// PointEdgeDistanceType / PointTriangleDistanceType / EdgeEdgeDistanceType as int (0 for planes)
    int distance_type = 0;
    std::array<Index, 4> vertices { -1, -1, -1, -1 }; ///< full-mesh vertex indices
    int plane = -1; ///< VERTEX_PLANE: index among the scene's planes
    double mollifier_threshold = 0; ///< EDGE_EDGE: eps_x at rest positions
    double distance_squared = 0; ///< at the state the set was built for (m^2)

    int num_vertices() const { return kernels::contact_num_vertices(kind); }
};

using ContactSet = std::vector<Contact>;

/// Vertex v of the flattened #V*dim positions x as a 3D point (z = 0 in 2D).
inline Eigen::Vector3d vertex_point(const VectorXd& x, Index v, int dim)
{
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    p.head(dim) = x.segment(v * dim, dim);
    return p;
}

} // namespace diffipc
