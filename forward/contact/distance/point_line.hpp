#pragma once
/// @file point_line.hpp
/// Squared distance from a point to the infinite line through two points,
/// with gradient and Hessian. Derivatives are vertex-major in argument order
/// (p, e0, e1), xyz per vertex.

#include <Eigen/Core>

namespace diffipc {

/// @brief Squared distance from p to the infinite line through e0 and e1,
/// \f$ |(e_0 - p) \times (e_1 - p)|^2 / |e_1 - e_0|^2 \f$.
/// @param p   3 point, m (2D callers set z = 0)
/// @param e0  3 first point of the line, m
/// @param e1  3 second point of the line, m; e1 != e0
/// @return squared distance, m^2
double point_line_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1);

/// @brief Gradient of point_line_distance.
/// @param p, e0, e1  as in point_line_distance
/// @return 9 vector (d/dp, d/de0, d/de1), m
Eigen::Matrix<double, 9, 1> point_line_distance_gradient(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1);

/// @brief Hessian of point_line_distance.
/// @param p, e0, e1  as in point_line_distance
/// @return 9 x 9, rows and columns ordered (p, e0, e1), dimensionless
Eigen::Matrix<double, 9, 9> point_line_distance_hessian(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1);

} // namespace diffipc
