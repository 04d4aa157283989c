#include "forward/contact/distance/line_line.hpp"

#include "forward/kernels/distance/line_line.hpp"
#include "forward/kernels/eigen_bridge.hpp"

namespace diffipc {

using kernels::kernel_matrix;
using kernels::kernel_vector;
using kernels::to_vec3;

double line_line_distance(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    return kernels::line_line_distance(to_vec3(ea0), to_vec3(ea1), to_vec3(eb0), to_vec3(eb1));
}

Eigen::Matrix<double, 12, 1> line_line_distance_gradient(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    return kernel_vector<12>([&](double* g) {
        kernels::line_line_distance_gradient(to_vec3(ea0), to_vec3(ea1), to_vec3(eb0), to_vec3(eb1), g);
    });
}

Eigen::Matrix<double, 12, 12> line_line_distance_hessian(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    return kernel_matrix<12>([&](double* H) {
        kernels::line_line_distance_hessian(to_vec3(ea0), to_vec3(ea1), to_vec3(eb0), to_vec3(eb1), H);
    });
}

} // namespace diffipc
