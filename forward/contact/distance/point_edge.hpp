#pragma once
/// @file point_edge.hpp
/// Squared distance from a point to a segment, with gradient and Hessian.
/// The closest-feature type (distance_type.hpp) picks the smooth formula:
/// point-point to an endpoint or point-line to the interior. Derivatives are
/// vertex-major in argument order (p, e0, e1), xyz per vertex; vertices the
/// type does not involve get zeros.

#include "forward/contact/distance/distance_type.hpp"

#include <Eigen/Core>

namespace diffipc {

/// @brief Squared distance from p to the segment (e0, e1) for a given closest-feature type.
/// @param p       3 point, m (2D callers set z = 0)
/// @param e0, e1  3 segment end points, m
/// @param type    closest feature, usually point_edge_distance_type(p, e0, e1)
/// @return squared distance, m^2
double point_edge_distance(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1, PointEdgeDistanceType type);
/// @brief Squared distance from p to the segment (e0, e1) (classifies first).
double point_edge_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1);

/// @brief Gradient of point_edge_distance for a given type.
/// @param p, e0, e1, type  as in point_edge_distance
/// @return 9 vector (d/dp, d/de0, d/de1), m
Eigen::Matrix<double, 9, 1> point_edge_distance_gradient(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1, PointEdgeDistanceType type);
/// @brief Gradient of point_edge_distance (classifies first).
Eigen::Matrix<double, 9, 1> point_edge_distance_gradient(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1);

/// @brief Hessian of point_edge_distance for a given type.
/// @param p, e0, e1, type  as in point_edge_distance
/// @return 9 x 9, rows and columns ordered (p, e0, e1), dimensionless
Eigen::Matrix<double, 9, 9> point_edge_distance_hessian(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1, PointEdgeDistanceType type);
/// @brief Hessian of point_edge_distance (classifies first).
Eigen::Matrix<double, 9, 9> point_edge_distance_hessian(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1);

} // namespace diffipc
