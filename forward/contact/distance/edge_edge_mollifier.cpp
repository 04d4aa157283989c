#include "forward/contact/distance/edge_edge_mollifier.hpp"

#include "forward/contact/distance/distance_kernels.hpp"

#include <Eigen/Geometry>

namespace diffipc {

namespace {
    // Kernel variables a = ea1 - ea0, b = eb1 - eb0. For the pull-back they
    // are rewritten in variables sharing the vertex ea0, y1 = ea1 - ea0,
    // y2 = eb0 - ea0, y3 = eb1 - ea0, i.e. (a, b) = (y1, y3 - y2).
    constexpr std::array<int, 3> PLUS { 1, 2, 3 };
    constexpr int MINUS = 0;

    Eigen::Matrix<double, 12, 1> pull_back_gradient(const distance_kernels::Vector<2>& g)
    {
        distance_kernels::Vector<3> gy;
        gy << g.segment<3>(0), -g.segment<3>(3), g.segment<3>(3);
        return distance_kernels::pull_back_gradient<3>(gy, PLUS, MINUS);
    }

    Eigen::Matrix<double, 12, 12> pull_back_hessian(const distance_kernels::Matrix<2>& H)
    {
        const Eigen::Matrix3d Haa = H.block<3, 3>(0, 0), Hab = H.block<3, 3>(0, 3), Hbb = H.block<3, 3>(3, 3);
        distance_kernels::Matrix<3> Hy;
        Hy << Haa, -Hab, Hab, //
            -Hab.transpose(), Hbb, -Hbb, //
            Hab.transpose(), -Hbb, Hbb;
        return distance_kernels::pull_back_hessian<3>(Hy, PLUS, MINUS);
    }

    // IPC's choice (Li et al. 2020): the mollifier acts below 0.1% of the
    // rest cross product's squared norm, i.e. below an angle of ~1.8 degrees.
    constexpr double MOLLIFIER_THRESHOLD_SCALE = 1e-3;
} // namespace

double edge_edge_cross_squarednorm(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    return (ea1 - ea0).cross(eb1 - eb0).squaredNorm();
}

Eigen::Matrix<double, 12, 1> edge_edge_cross_squarednorm_gradient(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    distance_kernels::Vector<2> g;
    distance_kernels::cross_squarednorm(ea1 - ea0, eb1 - eb0, &g, nullptr);
    return pull_back_gradient(g);
}

Eigen::Matrix<double, 12, 12> edge_edge_cross_squarednorm_hessian(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    distance_kernels::Matrix<2> H;
    distance_kernels::cross_squarednorm(ea1 - ea0, eb1 - eb0, nullptr, &H);
    return pull_back_hessian(H);
}

double edge_edge_mollifier_threshold(const Eigen::Vector3d& ea0_rest, const Eigen::Vector3d& ea1_rest,
    const Eigen::Vector3d& eb0_rest, const Eigen::Vector3d& eb1_rest)
{
    return MOLLIFIER_THRESHOLD_SCALE * (ea1_rest - ea0_rest).squaredNorm() * (eb1_rest - eb0_rest).squaredNorm();
}

Eigen::Matrix<double, 12, 1> edge_edge_mollifier_threshold_gradient(const Eigen::Vector3d& ea0_rest,
    const Eigen::Vector3d& ea1_rest, const Eigen::Vector3d& eb0_rest, const Eigen::Vector3d& eb1_rest)
{
    const Eigen::Vector3d a = ea1_rest - ea0_rest, b = eb1_rest - eb0_rest;
    distance_kernels::Vector<2> g;
    g << 2 * MOLLIFIER_THRESHOLD_SCALE * b.squaredNorm() * a, 2 * MOLLIFIER_THRESHOLD_SCALE * a.squaredNorm() * b;
    return pull_back_gradient(g);
}

// Each scalar form is a polynomial in s = x / eps_x in [0, 1) over a power
// of eps_x, as in the paper; `!(x < eps_x)` also sends eps_x <= 0 and NaN
// to the unmollified branch instead of dividing by zero.

double edge_edge_mollifier(double x, double eps_x)
{
    if (!(x < eps_x))
        return 1;
    const double s = x / eps_x;
    return (2 - s) * s;
}

double edge_edge_mollifier_gradient(double x, double eps_x)
{
    if (!(x < eps_x))
        return 0;
    return 2 * (1 - x / eps_x) / eps_x;
}

double edge_edge_mollifier_hessian(double x, double eps_x)
{
    if (!(x < eps_x))
        return 0;
    return -2 / (eps_x * eps_x);
}

double edge_edge_mollifier_gradient_wrt_eps_x(double x, double eps_x)
{
    if (!(x < eps_x))
        return 0;
    const double s = x / eps_x;
    return -2 * s * (1 - s) / eps_x;
}

double edge_edge_mollifier_gradient_jacobian_wrt_eps_x(double x, double eps_x)
{
    if (!(x < eps_x))
        return 0;
    return 2 * (2 * (x / eps_x) - 1) / (eps_x * eps_x);
}

double edge_edge_mollifier(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0,
    const Eigen::Vector3d& eb1, double eps_x)
{
    return edge_edge_mollifier(edge_edge_cross_squarednorm(ea0, ea1, eb0, eb1), eps_x);
}

Eigen::Matrix<double, 12, 1> edge_edge_mollifier_gradient(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
    const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double eps_x)
{
    const double x = edge_edge_cross_squarednorm(ea0, ea1, eb0, eb1);
    if (!(x < eps_x)) // the common case: skip the cross-product gradient
        return Eigen::Matrix<double, 12, 1>::Zero();
    return edge_edge_mollifier_gradient(x, eps_x) * edge_edge_cross_squarednorm_gradient(ea0, ea1, eb0, eb1);
}

Eigen::Matrix<double, 12, 12> edge_edge_mollifier_hessian(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
    const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double eps_x)
{
    const Eigen::Vector3d a = ea1 - ea0, b = eb1 - eb0;
    distance_kernels::Vector<2> g;
    distance_kernels::Matrix<2> H;
    const double x = distance_kernels::cross_squarednorm(a, b, &g, &H);
    if (!(x < eps_x))
        return Eigen::Matrix<double, 12, 12>::Zero();
    const distance_kernels::Matrix<2> Hm
        = edge_edge_mollifier_hessian(x, eps_x) * g * g.transpose() + edge_edge_mollifier_gradient(x, eps_x) * H;
    return pull_back_hessian(Hm);
}

double edge_edge_mollifier_gradient_wrt_eps_x(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1,
    const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double eps_x)
{
    return edge_edge_mollifier_gradient_wrt_eps_x(edge_edge_cross_squarednorm(ea0, ea1, eb0, eb1), eps_x);
}

Eigen::Matrix<double, 12, 1> edge_edge_mollifier_gradient_jacobian_wrt_eps_x(const Eigen::Vector3d& ea0,
    const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1, double eps_x)
{
    const double x = edge_edge_cross_squarednorm(ea0, ea1, eb0, eb1);
    if (!(x < eps_x))
        return Eigen::Matrix<double, 12, 1>::Zero();
    return edge_edge_mollifier_gradient_jacobian_wrt_eps_x(x, eps_x)
        * edge_edge_cross_squarednorm_gradient(ea0, ea1, eb0, eb1);
}

} // namespace diffipc
