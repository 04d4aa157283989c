#pragma once
/// @file point_edge.hpp
/// The squared distance from a
/// point to a segment for a closest-feature type (point-point to an endpoint, point-line to the
/// interior), with gradient and Hessian. Derivatives are vertex-major in argument order
/// (p, e0, e1), xyz per vertex, zeros for vertices the type does not involve; Hessians row-major.

#include "forward/kernels/distance/distance_type.hpp"

namespace diffipc::kernels {

/// @brief Squared distance from p to the segment (e0, e1) for `type` (m^2).
template <class T>
DIFFIPC_HD inline T point_edge_distance(
    const Vec3<T>& p, const Vec3<T>& e0, const Vec3<T>& e1, PointEdgeDistanceType type)
{
    return distance_type_detail::point_edge_distance(p, e0, e1, type);
}

/// @brief Squared distance from p to the segment (e0, e1), classifying first.
template <class T> DIFFIPC_HD inline T point_edge_distance(const Vec3<T>& p, const Vec3<T>& e0, const Vec3<T>& e1)
{
    return point_edge_distance(p, e0, e1, point_edge_distance_type(p, e0, e1));
}

/// @brief Gradient of point_edge_distance for `type`. @param g out: 9 (d/dp, d/de0, d/de1), m
template <class T>
DIFFIPC_HD inline void point_edge_distance_gradient(
    const Vec3<T>& p, const Vec3<T>& e0, const Vec3<T>& e1, PointEdgeDistanceType type, T* g)
{
    T local[6];
    switch (type) {
    case PointEdgeDistanceType::P_E0: {
        const int ids[2] = { 0, 1 };
        point_point_distance_gradient(p, e0, local);
        distance_kernels::scatter_gradient<3, 2>(local, ids, g);
        return;
    }
    case PointEdgeDistanceType::P_E1: {
        const int ids[2] = { 0, 2 };
        point_point_distance_gradient(p, e1, local);
        distance_kernels::scatter_gradient<3, 2>(local, ids, g);
        return;
    }
    case PointEdgeDistanceType::P_E:
        point_line_distance_gradient(p, e0, e1, g);
        return;
    }
    for (int k = 0; k < 9; ++k)
        g[k] = 0;
}

/// @brief Hessian of point_edge_distance for `type`. @param H out: 9 x 9 row-major, ordered (p, e0, e1)
template <class T>
DIFFIPC_HD inline void point_edge_distance_hessian(
    const Vec3<T>& p, const Vec3<T>& e0, const Vec3<T>& e1, PointEdgeDistanceType type, T* H)
{
    T local[36];
    switch (type) {
    case PointEdgeDistanceType::P_E0: {
        const int ids[2] = { 0, 1 };
        point_point_distance_hessian(p, e0, local);
        distance_kernels::scatter_hessian<3, 2>(local, ids, H);
        return;
    }
    case PointEdgeDistanceType::P_E1: {
        const int ids[2] = { 0, 2 };
        point_point_distance_hessian(p, e1, local);
        distance_kernels::scatter_hessian<3, 2>(local, ids, H);
        return;
    }
    case PointEdgeDistanceType::P_E:
        point_line_distance_hessian(p, e0, e1, H);
        return;
    }
    for (int k = 0; k < 81; ++k)
        H[k] = 0;
}

} // namespace diffipc::kernels
