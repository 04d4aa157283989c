#include "forward/contact/distance/point_line.hpp"

#include "forward/kernels/distance/point_line.hpp"
#include "forward/kernels/eigen_bridge.hpp"

namespace diffipc {

using kernels::kernel_matrix;
using kernels::kernel_vector;
using kernels::to_vec3;

double point_line_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1)
{
    return kernels::point_line_distance(to_vec3(p), to_vec3(e0), to_vec3(e1));
}

Eigen::Matrix<double, 9, 1> point_line_distance_gradient(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1)
{
    return kernel_vector<9>(
        [&](double* g) { kernels::point_line_distance_gradient(to_vec3(p), to_vec3(e0), to_vec3(e1), g); });
}

Eigen::Matrix<double, 9, 9> point_line_distance_hessian(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1)
{
    return kernel_matrix<9>(
        [&](double* H) { kernels::point_line_distance_hessian(to_vec3(p), to_vec3(e0), to_vec3(e1), H); });
}

} // namespace diffipc
