#include "forward/contact/distance/edge_edge_mollifier.hpp"

#include "forward/kernels/distance/edge_edge_mollifier.hpp"
#include "forward/kernels/eigen_bridge.hpp"

namespace diffipc {

using kernels::kernel_matrix;
using kernels::kernel_vector;
using kernels::to_vec3;

double edge_edge_cross_squarednorm(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    return kernels::edge_edge_cross_squarednorm(to_vec3(ea0), to_vec3(ea1), to_vec3(eb0), to_vec3(eb1));
}

Eigen::Matrix<double, 12, 1> edge_edge_cross_squarednorm_gradient(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    return kernel_vector<12>([&](double* g) {
        kernels::edge_edge_cross_squarednorm_gradient(to_vec3(ea0), to_vec3(ea1), to_vec3(eb0), to_vec3(eb1), g);
    });
}

Eigen::Matrix<double, 12, 12> edge_edge_cross_squarednorm_hessian(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    return kernel_matrix<12>([&](double* H) {
        kernels::edge_edge_cross_squarednorm_hessian(to_vec3(ea0), to_vec3(ea1), to_vec3(eb0), to_vec3(eb1), H);
    });
}

double edge_edge_mollifier_threshold(const Eigen::Vector3d& ea0_rest, const Eigen::Vector3d& ea1_rest,
    const Eigen::Vector3d& eb0_rest, const Eigen::Vector3d& eb1_rest)
{
    return kernels::edge_edge_mollifier_threshold(
        to_vec3(ea0_rest), to_vec3(ea1_rest), to_vec3(eb0_rest), to_vec3(eb1_rest));
}

Eigen::Matrix<double, 12, 1> edge_edge_mollifier_threshold_gradient(const Eigen::Vector3d& ea0_rest,
    const Eigen::Vector3d& ea1_rest, const Eigen::Vector3d& eb0_rest, const Eigen::Vector3d& eb1_rest)
{
    return kernel_vector<12>([&](double* g) {
        kernels::edge_edge_mollifier_threshold_gradient(
            to_vec3(ea0_rest), to_vec3(ea1_rest), to_vec3(eb0_rest), to_vec3(eb1_rest), g);
    });
}

double edge_edge_mollifier(double x, double eps_x) { return kernels::edge_edge_mollifier(x, eps_x); }

double edge_edge_mollifier_gradient(double x, double eps_x) { return kernels::edge_edge_mollifier_gradient(x, eps_x); }

double edge_edge_mollifier_hessian(double x, double eps_x) { return kernels::edge_edge_mollifier_hessian(x, eps_x); }

double edge_edge_mollifier_gradient_wrt_eps_x(double x, double eps_x)
{
    return kernels::edge_edge_mollifier_gradient_wrt_eps_x(x, eps_x);
}

double edge_edge_mollifier_gradient_jacobian_wrt_eps_x(double x, double eps_x)
{
    return kernels::edge_edge_mollifier_gradient_jacobian_wrt_eps_x(x, eps_x);
}

double edge_edge_mollifier(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0,
    const Eigen::Vector3d& eb1, double eps_x)
{
    return kernels::edge_edge_mollifier(to_vec3(ea0), to_vec3(ea1), to_vec3(eb0), to_vec3(eb1), eps_x);
}

Eigen::Matrix<double, 12, 1> edge_edge_mollifier_gradient(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
    const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double eps_x)
{
    return kernel_vector<12>([&](double* g) {
        kernels::edge_edge_mollifier_gradient(to_vec3(ea0), to_vec3(ea1), to_vec3(eb0), to_vec3(eb1), eps_x, g);
    });
}

Eigen::Matrix<double, 12, 12> edge_edge_mollifier_hessian(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
    const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double eps_x)
{
    return kernel_matrix<12>([&](double* H) {
        kernels::edge_edge_mollifier_hessian(to_vec3(ea0), to_vec3(ea1), to_vec3(eb0), to_vec3(eb1), eps_x, H);
    });
}

double edge_edge_mollifier_gradient_wrt_eps_x(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
    const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double eps_x)
{
    return edge_edge_mollifier_gradient_wrt_eps_x(edge_edge_cross_squarednorm(ea0, ea1, eb0, eb1), eps_x);
}

Eigen::Matrix<double, 12, 1> edge_edge_mollifier_gradient_jacobian_wrt_eps_x(const Eigen::Vector3d& ea0,
    const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double eps_x)
{
    return kernel_vector<12>([&](double* g) {
        kernels::edge_edge_mollifier_gradient_jacobian_wrt_eps_x(
            to_vec3(ea0), to_vec3(ea1), to_vec3(eb0), to_vec3(eb1), eps_x, g);
    });
}

} // namespace diffipc
