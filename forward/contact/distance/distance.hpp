#pragma once
/// @file distance.hpp
/// Squared distances between points, lines, planes and the primitives built
/// from them (values only; gradients and Hessians are in the per-type files).
/// All functions take 3D points; 2D callers set z = 0.

#include "forward/contact/distance/distance_type.hpp"

namespace diffipc {

/// |p0 - p1|^2
double point_point_distance(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1);
/// Squared distance from p to the infinite line through e0, e1 (e0 != e1): |(e0 - p) x (e1 - p)|^2 / |e1 - e0|^2.
double point_line_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1);
/// Squared distance from p to the plane through t0, t1, t2 (non-degenerate): ((p - t0) . n)^2 / |n|^2, n = (t1 - t0) x (t2 - t0).
double point_plane_distance(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2);
/// Squared distance between the infinite lines through ea0, ea1 and eb0, eb1 (not parallel): ((ea0 - eb0) . n)^2 / |n|^2, n = (ea1 - ea0) x (eb1 - eb0).
double line_line_distance(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1);

/// Squared distance from p to the segment (e0, e1), using the given closest-feature type.
double point_edge_distance(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1, PointEdgeDistanceType type);
/// Squared distance from p to the segment (e0, e1).
double point_edge_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1);

double point_triangle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1,
    const Eigen::Vector3d& t2, PointTriangleDistanceType type);
/// Squared distance from p to the triangle (t0, t1, t2).
double point_triangle_distance(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2);

double edge_edge_distance(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0,
    const Eigen::Vector3d& eb1, EdgeEdgeDistanceType type);
/// Squared distance between the segments (ea0, ea1) and (eb0, eb1).
double edge_edge_distance(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1);

} // namespace diffipc
