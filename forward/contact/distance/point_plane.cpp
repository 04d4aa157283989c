#include "forward/contact/distance/point_plane.hpp"

#include "forward/contact/distance/distance_kernels.hpp"

namespace diffipc {

// Kernel variables r = p - t0, a = t1 - t0, b = t2 - t0: plus vertices (p, t1, t2), minus t0.

double point_plane_distance(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2)
{
    return distance_kernels::point_plane(p - t0, t1 - t0, t2 - t0, nullptr, nullptr);
}

Eigen::Matrix<double, 12, 1> point_plane_distance_gradient(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2)
{
    distance_kernels::Vector<3> g;
    distance_kernels::point_plane(p - t0, t1 - t0, t2 - t0, &g, nullptr);
    return distance_kernels::pull_back_gradient<3>(g, { 0, 2, 3 }, 1);
}

Eigen::Matrix<double, 12, 12> point_plane_distance_hessian(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2)
{
    distance_kernels::Matrix<3> H;
    distance_kernels::point_plane(p - t0, t1 - t0, t2 - t0, nullptr, &H);
    return distance_kernels::pull_back_hessian<3>(H, { 0, 2, 3 }, 1);
}

} // namespace diffipc
