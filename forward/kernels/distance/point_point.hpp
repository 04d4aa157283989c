#pragma once
/// @file point_point.hpp
/// The squared distance between
/// two points with gradient and Hessian. Derivatives are vertex-major in argument order, xyz per
/// vertex; Hessians row-major.

#include "forward/kernels/vec3.hpp"

namespace diffipc::kernels {

/// @brief \f$ |p_0 - p_1|^2 \f$ (m^2); 2D callers set z = 0.
template <class T> DIFFIPC_HD inline T point_point_distance(const Vec3<T>& p0, const Vec3<T>& p1)
{
    return squared_norm(p0 - p1);
}

/// @brief Gradient of point_point_distance, \f$ 2 (p_0 - p_1, p_1 - p_0) \f$.
/// @param g out: 6 (d/dp0, d/dp1), m
template <class T> DIFFIPC_HD inline void point_point_distance_gradient(const Vec3<T>& p0, const Vec3<T>& p1, T* g)
{
    const Vec3<T> d = 2.0 * (p0 - p1);
    g[0] = d.x;
    g[1] = d.y;
    g[2] = d.z;
    g[3] = -d.x;
    g[4] = -d.y;
    g[5] = -d.z;
}

/// @brief Hessian of point_point_distance, the constant 2 [[I, -I], [-I, I]].
/// @param H out: 6 x 6 row-major, rows and columns ordered (p0, p1)
template <class T> DIFFIPC_HD inline void point_point_distance_hessian(const Vec3<T>&, const Vec3<T>&, T* H)
{
    for (int r = 0; r < 6; ++r)
        for (int c = 0; c < 6; ++c)
            H[r * 6 + c] = r == c ? 2.0 : (r % 3 == c % 3 ? -2.0 : 0.0);
}

} // namespace diffipc::kernels
