#include "forward/contact/distance/edge_edge.hpp"

#include "forward/kernels/distance/edge_edge.hpp"
#include "forward/kernels/eigen_bridge.hpp"

namespace diffipc {

using kernels::kernel_matrix;
using kernels::kernel_vector;
using kernels::to_vec3;

double edge_edge_distance(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0,
    const Eigen::Vector3d& eb1, EdgeEdgeDistanceType type)
{
    return kernels::edge_edge_distance(to_vec3(ea0), to_vec3(ea1), to_vec3(eb0), to_vec3(eb1), type);
}

double edge_edge_distance(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    return edge_edge_distance(ea0, ea1, eb0, eb1, edge_edge_distance_type(ea0, ea1, eb0, eb1));
}

Eigen::Matrix<double, 12, 1> edge_edge_distance_gradient(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
    const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, EdgeEdgeDistanceType type)
{
    return kernel_vector<12>([&](double* g) {
        kernels::edge_edge_distance_gradient(to_vec3(ea0), to_vec3(ea1), to_vec3(eb0), to_vec3(eb1), type, g);
    });
}

Eigen::Matrix<double, 12, 1> edge_edge_distance_gradient(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    return edge_edge_distance_gradient(ea0, ea1, eb0, eb1, edge_edge_distance_type(ea0, ea1, eb0, eb1));
}

Eigen::Matrix<double, 12, 12> edge_edge_distance_hessian(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
    const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, EdgeEdgeDistanceType type)
{
    return kernel_matrix<12>([&](double* H) {
        kernels::edge_edge_distance_hessian(to_vec3(ea0), to_vec3(ea1), to_vec3(eb0), to_vec3(eb1), type, H);
    });
}

Eigen::Matrix<double, 12, 12> edge_edge_distance_hessian(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    return edge_edge_distance_hessian(ea0, ea1, eb0, eb1, edge_edge_distance_type(ea0, ea1, eb0, eb1));
}

} // namespace diffipc
