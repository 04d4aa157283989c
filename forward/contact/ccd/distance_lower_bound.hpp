#pragma once
/// @file distance_lower_bound.hpp
/// Certified lower bounds of (unsquared) distances between primitives, for
/// conservative CCD. Each function returns a double L with
///
///     0 <= L <= d(exact inputs)
///
/// where d is the exact Euclidean distance between the primitives spanned by
/// the given double coordinates, evaluated in real arithmetic. L is also close
/// to d: for well-shaped primitives d - L is a few hundred units of round-off
/// of the coordinates' differences (about 1e-14 relative); for slivers and
/// nearly parallel edges it grows towards the size of the sliver (see the
/// .cpp), which only costs false positives in CCD.
///
/// The proof model is IEEE 754 double arithmetic with round-to-nearest, no
/// -ffast-math, no overflow or underflow (coordinates' magnitudes between
/// about 1e-60 and 1e60). Fused multiply-adds only shrink the errors.
/// All functions take 3D points; 2D callers set z = 0.

#include <Eigen/Core>

namespace diffipc {

/// @brief Lower bound of |p0 - p1|.
double point_point_distance_lower_bound(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1);

/// @brief Lower bound of the distance from point p to the segment (e0, e1)
/// (a point if e0 == e1).
double point_edge_distance_lower_bound(const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1);

/// @brief Lower bound of the distance from point p to the triangle (t0, t1, t2)
/// (any shape, degenerate included).
double point_triangle_distance_lower_bound(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2);

/// @brief Lower bound of the distance between the segments (ea0, ea1) and
/// (eb0, eb1) (any configuration: parallel, collinear, degenerate).
double edge_edge_distance_lower_bound(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1);

} // namespace diffipc
