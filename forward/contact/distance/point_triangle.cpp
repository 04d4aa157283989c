#include "forward/contact/distance/point_triangle.hpp"

#include "forward/contact/distance/distance_kernels.hpp"
#include "forward/contact/distance/point_line.hpp"
#include "forward/contact/distance/point_plane.hpp"
#include "forward/contact/distance/point_point.hpp"

namespace diffipc {

using distance_kernels::scatter_gradient;
using distance_kernels::scatter_hessian;
using PT = PointTriangleDistanceType;

double point_triangle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1,
    const Eigen::Vector3d& t2, PointTriangleDistanceType type)
{
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

Eigen::Matrix<double, 12, 1> point_triangle_distance_gradient(const Eigen::Vector3d& p, const Eigen::Vector3d& t0,
    const Eigen::Vector3d& t1, const Eigen::Vector3d& t2, PointTriangleDistanceType type)
{
    // Vertex ids in (p, t0, t1, t2) of each sub-distance's arguments.
    switch (type) {
    case PT::P_T0:
        return scatter_gradient<4, 2>(point_point_distance_gradient(p, t0), { 0, 1 });
    case PT::P_T1:
        return scatter_gradient<4, 2>(point_point_distance_gradient(p, t1), { 0, 2 });
    case PT::P_T2:
        return scatter_gradient<4, 2>(point_point_distance_gradient(p, t2), { 0, 3 });
    case PT::P_E0:
        return scatter_gradient<4, 3>(point_line_distance_gradient(p, t0, t1), { 0, 1, 2 });
    case PT::P_E1:
        return scatter_gradient<4, 3>(point_line_distance_gradient(p, t1, t2), { 0, 2, 3 });
    case PT::P_E2:
        return scatter_gradient<4, 3>(point_line_distance_gradient(p, t2, t0), { 0, 3, 1 });
    case PT::P_T:
        return point_plane_distance_gradient(p, t0, t1, t2);
    }
    return Eigen::Matrix<double, 12, 1>::Zero();
}

Eigen::Matrix<double, 12, 1> point_triangle_distance_gradient(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2)
{
    return point_triangle_distance_gradient(p, t0, t1, t2, point_triangle_distance_type(p, t0, t1, t2));
}

Eigen::Matrix<double, 12, 12> point_triangle_distance_hessian(const Eigen::Vector3d& p, const Eigen::Vector3d& t0,
    const Eigen::Vector3d& t1, const Eigen::Vector3d& t2, PointTriangleDistanceType type)
{
    switch (type) {
    case PT::P_T0:
        return scatter_hessian<4, 2>(point_point_distance_hessian(p, t0), { 0, 1 });
    case PT::P_T1:
        return scatter_hessian<4, 2>(point_point_distance_hessian(p, t1), { 0, 2 });
    case PT::P_T2:
        return scatter_hessian<4, 2>(point_point_distance_hessian(p, t2), { 0, 3 });
    case PT::P_E0:
        return scatter_hessian<4, 3>(point_line_distance_hessian(p, t0, t1), { 0, 1, 2 });
    case PT::P_E1:
        return scatter_hessian<4, 3>(point_line_distance_hessian(p, t1, t2), { 0, 2, 3 });
    case PT::P_E2:
        return scatter_hessian<4, 3>(point_line_distance_hessian(p, t2, t0), { 0, 3, 1 });
    case PT::P_T:
        return point_plane_distance_hessian(p, t0, t1, t2);
    }
    return Eigen::Matrix<double, 12, 12>::Zero();
}

Eigen::Matrix<double, 12, 12> point_triangle_distance_hessian(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2)
{
    return point_triangle_distance_hessian(p, t0, t1, t2, point_triangle_distance_type(p, t0, t1, t2));
}

} // namespace diffipc
