#include "forward/contact/distance/point_line.hpp"

#include "forward/contact/distance/distance_kernels.hpp"

namespace diffipc {

// Kernel variables r = p - e0, e = e1 - e0: plus vertices (p, e1), minus e0.

double point_line_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1)
{
    return distance_kernels::point_line(p - e0, e1 - e0, nullptr, nullptr);
}

Eigen::Matrix<double, 9, 1> point_line_distance_gradient(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1)
{
    distance_kernels::Vector<2> g;
    distance_kernels::point_line(p - e0, e1 - e0, &g, nullptr);
    return distance_kernels::pull_back_gradient<2>(g, { 0, 2 }, 1);
}

Eigen::Matrix<double, 9, 9> point_line_distance_hessian(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1)
{
    distance_kernels::Matrix<2> H;
    distance_kernels::point_line(p - e0, e1 - e0, nullptr, &H);
    return distance_kernels::pull_back_hessian<2>(H, { 0, 2 }, 1);
}

} // namespace diffipc
