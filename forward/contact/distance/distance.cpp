#include "forward/contact/distance/distance.hpp"

#include <Eigen/Geometry>

namespace diffipc {

double point_point_distance(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1) { return (p0 - p1).squaredNorm(); }

double point_line_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1)
{
    return (e0 - p).cross(e1 - p).squaredNorm() / (e1 - e0).squaredNorm();
}

double point_plane_distance(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2)
{
    const Eigen::Vector3d n = (t1 - t0).cross(t2 - t0);
    const double h = (p - t0).dot(n);
    return h * h / n.squaredNorm();
}

double line_line_distance(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    const Eigen::Vector3d n = (ea1 - ea0).cross(eb1 - eb0);
    const double h = (ea0 - eb0).dot(n);
    return h * h / n.squaredNorm();
}

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

double point_triangle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1,
    const Eigen::Vector3d& t2, PointTriangleDistanceType type)
{
    using PT = PointTriangleDistanceType;
    switch (type) {
    case PT::P_T0:
        return point_point_distance(p, t0);
    case PT::P_T1:
        return point_point_distance(p, t1);
    case PT::P_T2:
        return point_point_distance(p, t2);
    case PT::P_E0:
        return point_line_distance(p, t0, t1);
    case PT::P_E1:
        return point_line_distance(p, t1, t2);
    case PT::P_E2:
        return point_line_distance(p, t2, t0);
    case PT::P_T:
        return point_plane_distance(p, t0, t1, t2);
    }
    return 0;
}

double point_triangle_distance(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2)
{
    return point_triangle_distance(p, t0, t1, t2, point_triangle_distance_type(p, t0, t1, t2));
}

double edge_edge_distance(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0,
    const Eigen::Vector3d& eb1, EdgeEdgeDistanceType type)
{
    using EE = EdgeEdgeDistanceType;
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

} // namespace diffipc
