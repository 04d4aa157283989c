#pragma once
/// @file point_plane.hpp
/// The squared distance from a
/// point to the plane through three points, with gradient and Hessian. Derivatives are
/// vertex-major in argument order (p, t0, t1, t2), xyz per vertex; Hessians row-major.

#include "forward/kernels/distance/distance_kernels.hpp"

namespace diffipc::kernels {

// Kernel variables r = p - t0, a = t1 - t0, b = t2 - t0: plus vertices (p, t1, t2), minus t0.

/// @brief \f$ ((p - t_0) \cdot n)^2 / |n|^2 \f$, \f$ n = (t_1 - t_0) \times (t_2 - t_0) \f$ (m^2);
/// t0, t1, t2 not collinear.
template <class T>
DIFFIPC_HD inline T point_plane_distance(const Vec3<T>& p, const Vec3<T>& t0, const Vec3<T>& t1, const Vec3<T>& t2)
{
    return distance_kernels::point_plane(p - t0, t1 - t0, t2 - t0, nullptr, nullptr);
}

/// @brief Gradient of point_plane_distance. @param g out: 12 (d/dp, d/dt0, d/dt1, d/dt2), m
template <class T>
DIFFIPC_HD inline void point_plane_distance_gradient(
    const Vec3<T>& p, const Vec3<T>& t0, const Vec3<T>& t1, const Vec3<T>& t2, T* g)
{
    T k[9];
    distance_kernels::point_plane(p - t0, t1 - t0, t2 - t0, k, nullptr);
    const int plus[3] = { 0, 2, 3 };
    distance_kernels::pull_back_gradient<3>(k, plus, 1, g);
}

/// @brief Hessian of point_plane_distance. @param H out: 12 x 12 row-major, ordered (p, t0, t1, t2)
template <class T>
DIFFIPC_HD inline void point_plane_distance_hessian(
    const Vec3<T>& p, const Vec3<T>& t0, const Vec3<T>& t1, const Vec3<T>& t2, T* H)
{
    T k[81];
    distance_kernels::point_plane(p - t0, t1 - t0, t2 - t0, nullptr, k);
    const int plus[3] = { 0, 2, 3 };
    distance_kernels::pull_back_hessian<3>(k, plus, 1, H);
}

} // namespace diffipc::kernels
