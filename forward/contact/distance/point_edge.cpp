#include "forward/contact/distance/point_edge.hpp"

#include "forward/kernels/distance/point_edge.hpp"
#include "forward/kernels/eigen_bridge.hpp"

namespace diffipc {

using kernels::kernel_matrix;
using kernels::kernel_vector;
using kernels::to_vec3;

double point_edge_distance(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1, PointEdgeDistanceType type)
{
    return kernels::point_edge_distance(to_vec3(p), to_vec3(e0), to_vec3(e1), type);
}

double point_edge_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1)
{
    return point_edge_distance(p, e0, e1, point_edge_distance_type(p, e0, e1));
}

Eigen::Matrix<double, 9, 1> point_edge_distance_gradient(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1, PointEdgeDistanceType type)
{
    return kernel_vector<9>(
        [&](double* g) { kernels::point_edge_distance_gradient(to_vec3(p), to_vec3(e0), to_vec3(e1), type, g); });
}

Eigen::Matrix<double, 9, 1> point_edge_distance_gradient(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1)
{
    return point_edge_distance_gradient(p, e0, e1, point_edge_distance_type(p, e0, e1));
}

Eigen::Matrix<double, 9, 9> point_edge_distance_hessian(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1, PointEdgeDistanceType type)
{
    return kernel_matrix<9>(
        [&](double* H) { kernels::point_edge_distance_hessian(to_vec3(p), to_vec3(e0), to_vec3(e1), type, H); });
}

Eigen::Matrix<double, 9, 9> point_edge_distance_hessian(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1)
{
    return point_edge_distance_hessian(p, e0, e1, point_edge_distance_type(p, e0, e1));
}

} // namespace diffipc
