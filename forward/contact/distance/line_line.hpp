#pragma once
/// @file line_line.hpp
/// Squared distance between two infinite lines, with gradient and Hessian.
/// Derivatives are vertex-major in argument order (ea0, ea1, eb0, eb1), xyz
/// per vertex.

#include <Eigen/Core>

namespace diffipc {

/// @brief Squared distance between the infinite lines through ea0, ea1 and eb0, eb1,
/// \f$ ((e_{a0} - e_{b0}) \cdot n)^2 / |n|^2 \f$ with \f$ n = (e_{a1} - e_{a0}) \times (e_{b1} - e_{b0}) \f$.
/// Undefined for parallel lines (n = 0); its derivatives grow like 1/|n| as
/// the lines become parallel, which is what the edge-edge mollifier tames.
/// @param ea0, ea1  3 points on line a, m
/// @param eb0, eb1  3 points on line b, m
/// @return squared distance, m^2
double line_line_distance(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1);

/// @brief Gradient of line_line_distance.
/// @param ea0, ea1, eb0, eb1  as in line_line_distance
/// @return 12 vector (d/dea0, d/dea1, d/deb0, d/deb1), m
Eigen::Matrix<double, 12, 1> line_line_distance_gradient(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1);

/// @brief Hessian of line_line_distance.
/// @param ea0, ea1, eb0, eb1  as in line_line_distance
/// @return 12 x 12, rows and columns ordered (ea0, ea1, eb0, eb1), dimensionless
Eigen::Matrix<double, 12, 12> line_line_distance_hessian(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1);

} // namespace diffipc
