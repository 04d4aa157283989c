#include "forward/contact/distance/edge_edge.hpp"

#include "forward/contact/distance/distance_kernels.hpp"
#include "forward/contact/distance/line_line.hpp"
#include "forward/contact/distance/point_line.hpp"
#include "forward/contact/distance/point_point.hpp"

namespace diffipc {

using distance_kernels::scatter_gradient;
using distance_kernels::scatter_hessian;
using EE = EdgeEdgeDistanceType;

double edge_edge_distance(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0,
    const Eigen::Vector3d& eb1, EdgeEdgeDistanceType type)
{
    switch (type) {
    case EE::EA0_EB0:
        return point_point_distance(ea0, eb0);
    case EE::EA0_EB1:
        return point_point_distance(ea0, eb1);
    case EE::EA1_EB0:
        return point_point_distance(ea1, eb0);
    case EE::EA1_EB1:
        return point_point_distance(ea1, eb1);
    case EE::EA_EB0:
        return point_line_distance(eb0, ea0, ea1);
    case EE::EA_EB1:
        return point_line_distance(eb1, ea0, ea1);
    case EE::EA0_EB:
        return point_line_distance(ea0, eb0, eb1);
    case EE::EA1_EB:
        return point_line_distance(ea1, eb0, eb1);
    case EE::EA_EB:
        return line_line_distance(ea0, ea1, eb0, eb1);
    }
    return 0;
}

double edge_edge_distance(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    return edge_edge_distance(ea0, ea1, eb0, eb1, edge_edge_distance_type(ea0, ea1, eb0, eb1));
}

Eigen::Matrix<double, 12, 1> edge_edge_distance_gradient(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
    const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, EdgeEdgeDistanceType type)
{
    // Vertex ids in (ea0, ea1, eb0, eb1) of each sub-distance's arguments.
    switch (type) {
    case EE::EA0_EB0:
        return scatter_gradient<4, 2>(point_point_distance_gradient(ea0, eb0), { 0, 2 });
    case EE::EA0_EB1:
        return scatter_gradient<4, 2>(point_point_distance_gradient(ea0, eb1), { 0, 3 });
    case EE::EA1_EB0:
        return scatter_gradient<4, 2>(point_point_distance_gradient(ea1, eb0), { 1, 2 });
    case EE::EA1_EB1:
        return scatter_gradient<4, 2>(point_point_distance_gradient(ea1, eb1), { 1, 3 });
    case EE::EA_EB0:
        return scatter_gradient<4, 3>(point_line_distance_gradient(eb0, ea0, ea1), { 2, 0, 1 });
    case EE::EA_EB1:
        return scatter_gradient<4, 3>(point_line_distance_gradient(eb1, ea0, ea1), { 3, 0, 1 });
    case EE::EA0_EB:
        return scatter_gradient<4, 3>(point_line_distance_gradient(ea0, eb0, eb1), { 0, 2, 3 });
    case EE::EA1_EB:
        return scatter_gradient<4, 3>(point_line_distance_gradient(ea1, eb0, eb1), { 1, 2, 3 });
    case EE::EA_EB:
        return line_line_distance_gradient(ea0, ea1, eb0, eb1);
    }
    return Eigen::Matrix<double, 12, 1>::Zero();
}

Eigen::Matrix<double, 12, 1> edge_edge_distance_gradient(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    return edge_edge_distance_gradient(ea0, ea1, eb0, eb1, edge_edge_distance_type(ea0, ea1, eb0, eb1));
}

Eigen::Matrix<double, 12, 12> edge_edge_distance_hessian(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
    const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, EdgeEdgeDistanceType type)
{
    switch (type) {
    case EE::EA0_EB0:
        return scatter_hessian<4, 2>(point_point_distance_hessian(ea0, eb0), { 0, 2 });
    case EE::EA0_EB1:
        return scatter_hessian<4, 2>(point_point_distance_hessian(ea0, eb1), { 0, 3 });
    case EE::EA1_EB0:
        return scatter_hessian<4, 2>(point_point_distance_hessian(ea1, eb0), { 1, 2 });
    case EE::EA1_EB1:
        return scatter_hessian<4, 2>(point_point_distance_hessian(ea1, eb1), { 1, 3 });
    case EE::EA_EB0:
        return scatter_hessian<4, 3>(point_line_distance_hessian(eb0, ea0, ea1), { 2, 0, 1 });
    case EE::EA_EB1:
        return scatter_hessian<4, 3>(point_line_distance_hessian(eb1, ea0, ea1), { 3, 0, 1 });
    case EE::EA0_EB:
        return scatter_hessian<4, 3>(point_line_distance_hessian(ea0, eb0, eb1), { 0, 2, 3 });
    case EE::EA1_EB:
        return scatter_hessian<4, 3>(point_line_distance_hessian(ea1, eb0, eb1), { 1, 2, 3 });
    case EE::EA_EB:
        return line_line_distance_hessian(ea0, ea1, eb0, eb1);
    }
    return Eigen::Matrix<double, 12, 12>::Zero();
}

Eigen::Matrix<double, 12, 12> edge_edge_distance_hessian(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    return edge_edge_distance_hessian(ea0, ea1, eb0, eb1, edge_edge_distance_type(ea0, ea1, eb0, eb1));
}

} // namespace diffipc
