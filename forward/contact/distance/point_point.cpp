#include "forward/contact/distance/point_point.hpp"

namespace diffipc {

double point_point_distance(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1) { return (p0 - p1).squaredNorm(); }

Eigen::Matrix<double, 6, 1> point_point_distance_gradient(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1)
{
    Eigen::Matrix<double, 6, 1> g;
    g.head<3>() = 2 * (p0 - p1);
    g.tail<3>() = -g.head<3>();
    return g;
}

Eigen::Matrix<double, 6, 6> point_point_distance_hessian(const Eigen::Vector3d&, const Eigen::Vector3d&)
{
    Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
    H.diagonal().setConstant(2);
    H.block<3, 3>(0, 3).diagonal().setConstant(-2);
    H.block<3, 3>(3, 0).diagonal().setConstant(-2);
    return H;
}

} // namespace diffipc
