#include "forward/contact/distance/point_edge.hpp"

#include "forward/contact/distance/distance_kernels.hpp"
#include "forward/contact/distance/point_line.hpp"
#include "forward/contact/distance/point_point.hpp"

namespace diffipc {

using distance_kernels::scatter_gradient;
using distance_kernels::scatter_hessian;

double point_edge_distance(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1, PointEdgeDistanceType type)
{
    switch (type) {
    case PointEdgeDistanceType::P_E0:
        return point_point_distance(p, e0);
    case PointEdgeDistanceType::P_E1:
        return point_point_distance(p, e1);
    case PointEdgeDistanceType::P_E:
        return point_line_distance(p, e0, e1);
    }
    return 0;
}

double point_edge_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1)
{
    return point_edge_distance(p, e0, e1, point_edge_distance_type(p, e0, e1));
}

Eigen::Matrix<double, 9, 1> point_edge_distance_gradient(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1, PointEdgeDistanceType type)
{
    switch (type) {
    case PointEdgeDistanceType::P_E0:
        return scatter_gradient<3, 2>(point_point_distance_gradient(p, e0), { 0, 1 });
    case PointEdgeDistanceType::P_E1:
        return scatter_gradient<3, 2>(point_point_distance_gradient(p, e1), { 0, 2 });
    case PointEdgeDistanceType::P_E:
        return point_line_distance_gradient(p, e0, e1);
    }
    return Eigen::Matrix<double, 9, 1>::Zero();
}

Eigen::Matrix<double, 9, 1> point_edge_distance_gradient(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1)
{
    return point_edge_distance_gradient(p, e0, e1, point_edge_distance_type(p, e0, e1));
}

Eigen::Matrix<double, 9, 9> point_edge_distance_hessian(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1, PointEdgeDistanceType type)
{
    switch (type) {
    case PointEdgeDistanceType::P_E0:
        return scatter_hessian<3, 2>(point_point_distance_hessian(p, e0), { 0, 1 });
    case PointEdgeDistanceType::P_E1:
        return scatter_hessian<3, 2>(point_point_distance_hessian(p, e1), { 0, 2 });
    case PointEdgeDistanceType::P_E:
        return point_line_distance_hessian(p, e0, e1);
    }
    return Eigen::Matrix<double, 9, 9>::Zero();
}

Eigen::Matrix<double, 9, 9> point_edge_distance_hessian(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1)
{
    return point_edge_distance_hessian(p, e0, e1, point_edge_distance_type(p, e0, e1));
}

} // namespace diffipc
