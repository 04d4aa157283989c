#include "forward/contact/distance/point_triangle.hpp"

#include "forward/kernels/distance/point_triangle.hpp"
#include "forward/kernels/eigen_bridge.hpp"

namespace diffipc {

using kernels::kernel_matrix;
using kernels::kernel_vector;
using kernels::to_vec3;

double point_triangle_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1,
    const Eigen::Vector3d& t2, PointTriangleDistanceType type)
{
    return kernels::point_triangle_distance(to_vec3(p), to_vec3(t0), to_vec3(t1), to_vec3(t2), type);
}

double point_triangle_distance(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2)
{
    return point_triangle_distance(p, t0, t1, t2, point_triangle_distance_type(p, t0, t1, t2));
}

Eigen::Matrix<double, 12, 1> point_triangle_distance_gradient(const Eigen::Vector3d& p, const Eigen::Vector3d& t0,
    const Eigen::Vector3d& t1, const Eigen::Vector3d& t2, PointTriangleDistanceType type)
{
    return kernel_vector<12>([&](double* g) {
        kernels::point_triangle_distance_gradient(to_vec3(p), to_vec3(t0), to_vec3(t1), to_vec3(t2), type, g);
    });
}

Eigen::Matrix<double, 12, 1> point_triangle_distance_gradient(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2)
{
    return point_triangle_distance_gradient(p, t0, t1, t2, point_triangle_distance_type(p, t0, t1, t2));
}

Eigen::Matrix<double, 12, 12> point_triangle_distance_hessian(const Eigen::Vector3d& p, const Eigen::Vector3d& t0,
    const Eigen::Vector3d& t1, const Eigen::Vector3d& t2, PointTriangleDistanceType type)
{
    return kernel_matrix<12>([&](double* H) {
        kernels::point_triangle_distance_hessian(to_vec3(p), to_vec3(t0), to_vec3(t1), to_vec3(t2), type, H);
    });
}

Eigen::Matrix<double, 12, 12> point_triangle_distance_hessian(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2)
{
    return point_triangle_distance_hessian(p, t0, t1, t2, point_triangle_distance_type(p, t0, t1, t2));
}

} // namespace diffipc
