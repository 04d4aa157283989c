#pragma once
/// @file point_triangle.hpp
/// Squared distance from a point to a triangle, with gradient and Hessian.
/// The closest-feature type (distance_type.hpp) picks the smooth formula:
/// point-point to a corner, point-line to an edge (E0 = (t0, t1),
/// E1 = (t1, t2), E2 = (t2, t0)) or point-plane. Derivatives are vertex-major
/// in argument order (p, t0, t1, t2), xyz per vertex; vertices the type does
/// not involve get zeros.

#include "forward/contact/distance/distance_type.hpp"

#include <Eigen/Core>

namespace diffipc {

/// @brief Squared distance from p to the triangle (t0, t1, t2) for a given closest-feature type.
/// @param p           3 point, m
/// @param t0, t1, t2  3 triangle corners, m
/// @param type        closest feature, usually point_triangle_distance_type(p, t0, t1, t2)
/// @return squared distance, m^2
double point_triangle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1,
    const Eigen::Vector3d& t2, PointTriangleDistanceType type);
/// @brief Squared distance from p to the triangle (t0, t1, t2) (classifies first).
double point_triangle_distance(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2);

/// @brief Gradient of point_triangle_distance for a given type.
/// @param p, t0, t1, t2, type  as in point_triangle_distance
/// @return 12 vector (d/dp, d/dt0, d/dt1, d/dt2), m
Eigen::Matrix<double, 12, 1> point_triangle_distance_gradient(const Eigen::Vector3d& p, const Eigen::Vector3d& t0,
    const Eigen::Vector3d& t1, const Eigen::Vector3d& t2, PointTriangleDistanceType type);
/// @brief Gradient of point_triangle_distance (classifies first).
Eigen::Matrix<double, 12, 1> point_triangle_distance_gradient(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2);

/// @brief Hessian of point_triangle_distance for a given type.
/// @param p, t0, t1, t2, type  as in point_triangle_distance
/// @return 12 x 12, rows and columns ordered (p, t0, t1, t2), dimensionless
Eigen::Matrix<double, 12, 12> point_triangle_distance_hessian(const Eigen::Vector3d& p, const Eigen::Vector3d& t0,
    const Eigen::Vector3d& t1, const Eigen::Vector3d& t2, PointTriangleDistanceType type);
/// @brief Hessian of point_triangle_distance (classifies first).
Eigen::Matrix<double, 12, 12> point_triangle_distance_hessian(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2);

} // namespace diffipc
