#pragma once
/// @file point_point.hpp
/// Squared distance between two points, with gradient and Hessian.
/// Derivatives are vertex-major in argument order, xyz per vertex.

#include <Eigen/Core>

namespace diffipc {

/// @brief Squared distance between two points, \f$ |p_0 - p_1|^2 \f$.
/// @param p0  3 point, m (2D callers set z = 0)
/// @param p1  3 point, m
/// @return squared distance, m^2
double point_point_distance(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1);

/// @brief Gradient of point_point_distance, \f$ 2 (p_0 - p_1, p_1 - p_0) \f$.
/// @param p0, p1  as in point_point_distance
/// @return 6 vector (d/dp0, d/dp1), m
Eigen::Matrix<double, 6, 1> point_point_distance_gradient(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1);

/// @brief Hessian of point_point_distance, the constant
/// \f$ 2 \begin{bmatrix} I & -I \\ -I & I \end{bmatrix} \f$.
/// @param p0, p1  as in point_point_distance (unused but kept for the uniform signature)
/// @return 6 x 6, rows and columns ordered (p0, p1), dimensionless
Eigen::Matrix<double, 6, 6> point_point_distance_hessian(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1);

} // namespace diffipc
