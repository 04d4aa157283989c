#include "forward/contact/distance/point_point.hpp"

#include "forward/kernels/distance/point_point.hpp"
#include "forward/kernels/eigen_bridge.hpp"

namespace diffipc {

using kernels::kernel_matrix;
using kernels::kernel_vector;
using kernels::to_vec3;

double point_point_distance(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1)
{
    return kernels::point_point_distance(to_vec3(p0), to_vec3(p1));
}

Eigen::Matrix<double, 6, 1> point_point_distance_gradient(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1)
{
    return kernel_vector<6>([&](double* g) { kernels::point_point_distance_gradient(to_vec3(p0), to_vec3(p1), g); });
}

Eigen::Matrix<double, 6, 6> point_point_distance_hessian(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1)
{
    return kernel_matrix<6>([&](double* H) { kernels::point_point_distance_hessian(to_vec3(p0), to_vec3(p1), H); });
}

} // namespace diffipc
