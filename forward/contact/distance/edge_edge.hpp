#pragma once
/// @file edge_edge.hpp
/// Squared distance between two segments, with gradient and Hessian. The
/// closest-feature type (distance_type.hpp) picks the smooth formula:
/// point-point between end points, point-line from an end point to the other
/// edge's interior, or line-line. Derivatives are vertex-major in argument
/// order (ea0, ea1, eb0, eb1), xyz per vertex; vertices the type does not
/// involve get zeros. Near-parallel edges make the line-line derivatives
/// large; multiply the barrier by edge_edge_mollifier (edge_edge_mollifier.hpp).

#include "forward/contact/distance/distance_type.hpp"

#include <Eigen/Core>

namespace diffipc {

/// @brief Squared distance between the segments (ea0, ea1) and (eb0, eb1) for a given closest-feature type.
/// @param ea0, ea1  3 end points of edge a, m
/// @param eb0, eb1  3 end points of edge b, m
/// @param type      closest features, usually edge_edge_distance_type(ea0, ea1, eb0, eb1)
/// @return squared distance, m^2
double edge_edge_distance(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0,
    const Eigen::Vector3d& eb1, EdgeEdgeDistanceType type);
/// @brief Squared distance between the segments (ea0, ea1) and (eb0, eb1) (classifies first).
double edge_edge_distance(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1);

/// @brief Gradient of edge_edge_distance for a given type.
/// @param ea0, ea1, eb0, eb1, type  as in edge_edge_distance
/// @return 12 vector (d/dea0, d/dea1, d/deb0, d/deb1), m
Eigen::Matrix<double, 12, 1> edge_edge_distance_gradient(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
    const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, EdgeEdgeDistanceType type);
/// @brief Gradient of edge_edge_distance (classifies first).
Eigen::Matrix<double, 12, 1> edge_edge_distance_gradient(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1);

/// @brief Hessian of edge_edge_distance for a given type.
/// @param ea0, ea1, eb0, eb1, type  as in edge_edge_distance
/// @return 12 x 12, rows and columns ordered (ea0, ea1, eb0, eb1), dimensionless
Eigen::Matrix<double, 12, 12> edge_edge_distance_hessian(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
    const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, EdgeEdgeDistanceType type);
/// @brief Hessian of edge_edge_distance (classifies first).
Eigen::Matrix<double, 12, 12> edge_edge_distance_hessian(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1);

} // namespace diffipc
