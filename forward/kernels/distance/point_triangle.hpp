#pragma once
/// @file point_triangle.hpp
/// The squared distance from a
/// point to a triangle for a closest-feature type (point-point to a corner, point-line to an
/// edge E0 = (t0, t1), E1 = (t1, t2), E2 = (t2, t0), or point-plane), with gradient and Hessian.
/// Derivatives are vertex-major in argument order (p, t0, t1, t2), xyz per vertex, zeros for
/// vertices the type does not involve; Hessians row-major.

#include "forward/kernels/distance/distance_type.hpp"
#include "forward/kernels/distance/point_plane.hpp"

namespace diffipc::kernels {

/// @brief Squared distance from p to the triangle (t0, t1, t2) for `type` (m^2).
template <class T>
DIFFIPC_HD inline T point_triangle_distance(
    const Vec3<T>& p, const Vec3<T>& t0, const Vec3<T>& t1, const Vec3<T>& t2, PointTriangleDistanceType type)
{
    using PT = PointTriangleDistanceType;
    switch (type) {
    case PT::P_T0:
        return point_point_distance(p, t0);
    case PT::P_T1:
        return point_point_distance(p, t1);
    case PT::P_T2:
        return point_point_distance(p, t2);
    case PT::P_E0:
        return point_line_distance(p, t0, t1);
    case PT::P_E1:
        return point_line_distance(p, t1, t2);
    case PT::P_E2:
        return point_line_distance(p, t2, t0);
    case PT::P_T:
        return point_plane_distance(p, t0, t1, t2);
    }
    return 0;
}

/// @brief Squared distance from p to the triangle (t0, t1, t2), classifying first.
template <class T>
DIFFIPC_HD inline T point_triangle_distance(const Vec3<T>& p, const Vec3<T>& t0, const Vec3<T>& t1, const Vec3<T>& t2)
{
    return point_triangle_distance(p, t0, t1, t2, point_triangle_distance_type(p, t0, t1, t2));
}

/// @brief Gradient of point_triangle_distance for `type`. @param g out: 12 (d/dp, d/dt0, d/dt1, d/dt2), m
template <class T>
DIFFIPC_HD inline void point_triangle_distance_gradient(
    const Vec3<T>& p, const Vec3<T>& t0, const Vec3<T>& t1, const Vec3<T>& t2, PointTriangleDistanceType type, T* g)
{
    using PT = PointTriangleDistanceType;
    using distance_kernels::scatter_gradient;
    T local[9];
    // Vertex ids in (p, t0, t1, t2) of each sub-distance's arguments.
    switch (type) {
    case PT::P_T0: {
        const int ids[2] = { 0, 1 };
        point_point_distance_gradient(p, t0, local);
        scatter_gradient<4, 2>(local, ids, g);
        return;
    }
    case PT::P_T1: {
        const int ids[2] = { 0, 2 };
        point_point_distance_gradient(p, t1, local);
        scatter_gradient<4, 2>(local, ids, g);
        return;
    }
    case PT::P_T2: {
        const int ids[2] = { 0, 3 };
        point_point_distance_gradient(p, t2, local);
        scatter_gradient<4, 2>(local, ids, g);
        return;
    }
    case PT::P_E0: {
        const int ids[3] = { 0, 1, 2 };
        point_line_distance_gradient(p, t0, t1, local);
        scatter_gradient<4, 3>(local, ids, g);
        return;
    }
    case PT::P_E1: {
        const int ids[3] = { 0, 2, 3 };
        point_line_distance_gradient(p, t1, t2, local);
        scatter_gradient<4, 3>(local, ids, g);
        return;
    }
    case PT::P_E2: {
        const int ids[3] = { 0, 3, 1 };
        point_line_distance_gradient(p, t2, t0, local);
        scatter_gradient<4, 3>(local, ids, g);
        return;
    }
    case PT::P_T:
        point_plane_distance_gradient(p, t0, t1, t2, g);
        return;
    }
    for (int k = 0; k < 12; ++k)
        g[k] = 0;
}

/// @brief Hessian of point_triangle_distance for `type`. @param H out: 12 x 12 row-major, ordered (p, t0, t1, t2)
template <class T>
DIFFIPC_HD inline void point_triangle_distance_hessian(
    const Vec3<T>& p, const Vec3<T>& t0, const Vec3<T>& t1, const Vec3<T>& t2, PointTriangleDistanceType type, T* H)
{
    using PT = PointTriangleDistanceType;
    using distance_kernels::scatter_hessian;
    T local[81];
    switch (type) {
    case PT::P_T0: {
        const int ids[2] = { 0, 1 };
        point_point_distance_hessian(p, t0, local);
        scatter_hessian<4, 2>(local, ids, H);
        return;
    }
    case PT::P_T1: {
        const int ids[2] = { 0, 2 };
        point_point_distance_hessian(p, t1, local);
        scatter_hessian<4, 2>(local, ids, H);
        return;
    }
    case PT::P_T2: {
        const int ids[2] = { 0, 3 };
        point_point_distance_hessian(p, t2, local);
        scatter_hessian<4, 2>(local, ids, H);
        return;
    }
    case PT::P_E0: {
        const int ids[3] = { 0, 1, 2 };
        point_line_distance_hessian(p, t0, t1, local);
        scatter_hessian<4, 3>(local, ids, H);
        return;
    }
    case PT::P_E1: {
        const int ids[3] = { 0, 2, 3 };
        point_line_distance_hessian(p, t1, t2, local);
        scatter_hessian<4, 3>(local, ids, H);
        return;
    }
    case PT::P_E2: {
        const int ids[3] = { 0, 3, 1 };
        point_line_distance_hessian(p, t2, t0, local);
        scatter_hessian<4, 3>(local, ids, H);
        return;
    }
    case PT::P_T:
        point_plane_distance_hessian(p, t0, t1, t2, H);
        return;
    }
    for (int k = 0; k < 144; ++k)
        H[k] = 0;
}

} // namespace diffipc::kernels
