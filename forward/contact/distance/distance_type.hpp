#pragma once
/// @file distance_type.hpp
/// Which pair of closest features realizes the distance between two
/// primitives. The squared distance of a primitive pair is the squared
/// distance of that feature pair (point-point, point-line, point-plane or
/// line-line), so each type picks a smooth formula and its derivatives.
/// Edges of a triangle: E0 = (t0, t1), E1 = (t1, t2), E2 = (t2, t0).

#include "forward/kernels/distance/distance_type.hpp"

#include <Eigen/Core>

namespace diffipc {

// One enum per concept, shared with the GPU path (forward/kernels/distance/distance_type.hpp).
using kernels::EdgeEdgeDistanceType;
using kernels::PointEdgeDistanceType;
using kernels::PointTriangleDistanceType;

/// @brief Closest-feature type of point p to segment (e0, e1), in 2D or 3D
/// (2D points have z = 0). A degenerate edge gives P_E0.
PointEdgeDistanceType point_edge_distance_type(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1);

/// @brief Closest-feature type of point p to triangle (t0, t1, t2). The plane
/// type is chosen only when the projection of p falls inside the triangle;
/// otherwise the closest of the three edges decides. A degenerate (zero-area)
/// triangle is treated through its edges.
PointTriangleDistanceType point_triangle_distance_type(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2);

/// @brief Closest-feature type of segments (ea0, ea1) and (eb0, eb1). The
/// minimum over [0,1]^2 is either at an interior critical point of the
/// line-line distance (only for non-parallel lines) or on the boundary, where
/// one endpoint meets the other segment; the smallest candidate wins, so
/// parallel and nearly parallel edges are handled without a threshold.
EdgeEdgeDistanceType edge_edge_distance_type(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1);

} // namespace diffipc
