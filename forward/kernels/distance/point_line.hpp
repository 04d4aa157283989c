#pragma once
/// @file point_line.hpp
/// The squared distance from a
/// point to the infinite line through two points, with gradient and Hessian. Derivatives are
/// vertex-major in argument order (p, e0, e1), xyz per vertex; Hessians row-major.

#include "forward/kernels/distance/distance_kernels.hpp"

namespace diffipc::kernels {

// Kernel variables r = p - e0, e = e1 - e0: plus vertices (p, e1), minus e0.

/// @brief \f$ |(e_0 - p) \times (e_1 - p)|^2 / |e_1 - e_0|^2 \f$ (m^2); requires e1 != e0.
template <class T> DIFFIPC_HD inline T point_line_distance(const Vec3<T>& p, const Vec3<T>& e0, const Vec3<T>& e1)
{
    return distance_kernels::point_line(p - e0, e1 - e0, nullptr, nullptr);
}

/// @brief Gradient of point_line_distance. @param g out: 9 (d/dp, d/de0, d/de1), m
template <class T>
DIFFIPC_HD inline void point_line_distance_gradient(const Vec3<T>& p, const Vec3<T>& e0, const Vec3<T>& e1, T* g)
{
    T k[6];
    distance_kernels::point_line(p - e0, e1 - e0, k, nullptr);
    const int plus[2] = { 0, 2 };
    distance_kernels::pull_back_gradient<2>(k, plus, 1, g);
}

/// @brief Hessian of point_line_distance. @param H out: 9 x 9 row-major, ordered (p, e0, e1)
template <class T>
DIFFIPC_HD inline void point_line_distance_hessian(const Vec3<T>& p, const Vec3<T>& e0, const Vec3<T>& e1, T* H)
{
    T k[36];
    distance_kernels::point_line(p - e0, e1 - e0, nullptr, k);
    const int plus[2] = { 0, 2 };
    distance_kernels::pull_back_hessian<2>(k, plus, 1, H);
}

} // namespace diffipc::kernels
