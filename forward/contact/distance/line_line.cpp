#include "forward/contact/distance/line_line.hpp"

#include "forward/contact/distance/distance_kernels.hpp"

namespace diffipc {

namespace {
    // Line-line is the point-plane kernel with r = ea0 - eb0, a = ea1 - ea0,
    // b = eb1 - eb0: the distance of ea0 to the plane through eb0 spanned by
    // both edge directions. For the pull-back these are rewritten in
    // variables sharing the vertex ea0, y1 = ea1 - ea0, y2 = eb0 - ea0,
    // y3 = eb1 - ea0, i.e. (r, a, b) = (-y2, y1, y3 - y2).
    constexpr std::array<int, 3> PLUS { 1, 2, 3 };
    constexpr int MINUS = 0;

    distance_kernels::Vector<3> to_shared_vertex(const distance_kernels::Vector<3>& g)
    {
        distance_kernels::Vector<3> gy;
        gy << g.segment<3>(3), -g.segment<3>(0) - g.segment<3>(6), g.segment<3>(6);
        return gy;
    }

    distance_kernels::Matrix<3> to_shared_vertex(const distance_kernels::Matrix<3>& H)
    {
        const auto B = [&](int i, int j) { return H.block<3, 3>(3 * i, 3 * j); };
        constexpr int r = 0, a = 1, b = 2;
        distance_kernels::Matrix<3> Hy;
        Hy.block<3, 3>(0, 0) = B(a, a);
        Hy.block<3, 3>(0, 3) = -B(a, r) - B(a, b);
        Hy.block<3, 3>(0, 6) = B(a, b);
        Hy.block<3, 3>(3, 3) = B(r, r) + B(r, b) + B(b, r) + B(b, b);
        Hy.block<3, 3>(3, 6) = -B(r, b) - B(b, b);
        Hy.block<3, 3>(6, 6) = B(b, b);
        Hy.block<3, 3>(3, 0) = Hy.block<3, 3>(0, 3).transpose();
        Hy.block<3, 3>(6, 0) = Hy.block<3, 3>(0, 6).transpose();
        Hy.block<3, 3>(6, 3) = Hy.block<3, 3>(3, 6).transpose();
        return Hy;
    }
} // namespace

double line_line_distance(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    return distance_kernels::point_plane(ea0 - eb0, ea1 - ea0, eb1 - eb0, nullptr, nullptr);
}

Eigen::Matrix<double, 12, 1> line_line_distance_gradient(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    distance_kernels::Vector<3> g;
    distance_kernels::point_plane(ea0 - eb0, ea1 - ea0, eb1 - eb0, &g, nullptr);
    return distance_kernels::pull_back_gradient<3>(to_shared_vertex(g), PLUS, MINUS);
}

Eigen::Matrix<double, 12, 12> line_line_distance_hessian(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    distance_kernels::Matrix<3> H;
    distance_kernels::point_plane(ea0 - eb0, ea1 - ea0, eb1 - eb0, nullptr, &H);
    return distance_kernels::pull_back_hessian<3>(to_shared_vertex(H), PLUS, MINUS);
}

} // namespace diffipc
