#pragma once
/// @file point_plane.hpp
/// Squared distance from a point to the plane through three points, with
/// gradient and Hessian. Derivatives are vertex-major in argument order
/// (p, t0, t1, t2), xyz per vertex.

#include <Eigen/Core>

namespace diffipc {

/// @brief Squared distance from p to the plane through t0, t1, t2,
/// \f$ ((p - t_0) \cdot n)^2 / |n|^2 \f$ with \f$ n = (t_1 - t_0) \times (t_2 - t_0) \f$.
/// @param p       3 point, m
/// @param t0, t1, t2  3 points spanning the plane (not collinear), m
/// @return squared distance, m^2
double point_plane_distance(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2);

/// @brief Gradient of point_plane_distance.
/// @param p, t0, t1, t2  as in point_plane_distance
/// @return 12 vector (d/dp, d/dt0, d/dt1, d/dt2), m
Eigen::Matrix<double, 12, 1> point_plane_distance_gradient(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2);

/// @brief Hessian of point_plane_distance.
/// @param p, t0, t1, t2  as in point_plane_distance
/// @return 12 x 12, rows and columns ordered (p, t0, t1, t2), dimensionless
Eigen::Matrix<double, 12, 12> point_plane_distance_hessian(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2);

} // namespace diffipc
