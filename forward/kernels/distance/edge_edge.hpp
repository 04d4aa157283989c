#pragma once
/// @file edge_edge.hpp
/// The squared distance between two
/// segments for a closest-feature type (point-point between end points, point-line from an end
/// point to the other edge's interior, or line-line), with gradient and Hessian. Derivatives are
/// vertex-major in argument order (ea0, ea1, eb0, eb1), xyz per vertex, zeros for vertices the
/// type does not involve; Hessians row-major. Multiply the barrier by the edge-edge mollifier
/// (edge_edge_mollifier.hpp) where the edges are nearly parallel.

#include "forward/kernels/distance/distance_type.hpp"
#include "forward/kernels/distance/line_line.hpp"

namespace diffipc::kernels {

namespace edge_edge_detail {
    /// The sub-distance of each type: its kind (0 point-point, 1 point-line, 2 line-line) and the
    /// ids in (ea0, ea1, eb0, eb1) of its arguments, in argument order.
    struct SubDistance {
        int kind;
        int ids[3];
    };
    DIFFIPC_HD inline SubDistance sub_distance(EdgeEdgeDistanceType type)
    {
        using EE = EdgeEdgeDistanceType;
        switch (type) {
        case EE::EA0_EB0:
            return { 0, { 0, 2, -1 } };
        case EE::EA0_EB1:
            return { 0, { 0, 3, -1 } };
        case EE::EA1_EB0:
            return { 0, { 1, 2, -1 } };
        case EE::EA1_EB1:
            return { 0, { 1, 3, -1 } };
        case EE::EA_EB0:
            return { 1, { 2, 0, 1 } };
        case EE::EA_EB1:
            return { 1, { 3, 0, 1 } };
        case EE::EA0_EB:
            return { 1, { 0, 2, 3 } };
        case EE::EA1_EB:
            return { 1, { 1, 2, 3 } };
        case EE::EA_EB:
            break;
        }
        return { 2, { -1, -1, -1 } };
    }
} // namespace edge_edge_detail

/// @brief Squared distance between the segments (ea0, ea1) and (eb0, eb1) for `type` (m^2).
template <class T>
DIFFIPC_HD inline T edge_edge_distance(
    const Vec3<T>& ea0, const Vec3<T>& ea1, const Vec3<T>& eb0, const Vec3<T>& eb1, EdgeEdgeDistanceType type)
{
    const Vec3<T>* v[4] = { &ea0, &ea1, &eb0, &eb1 };
    const edge_edge_detail::SubDistance sub = edge_edge_detail::sub_distance(type);
    if (sub.kind == 0)
        return point_point_distance(*v[sub.ids[0]], *v[sub.ids[1]]);
    if (sub.kind == 1)
        return point_line_distance(*v[sub.ids[0]], *v[sub.ids[1]], *v[sub.ids[2]]);
    return line_line_distance(ea0, ea1, eb0, eb1);
}

/// @brief Squared distance between the segments, classifying first.
template <class T>
DIFFIPC_HD inline T edge_edge_distance(const Vec3<T>& ea0, const Vec3<T>& ea1, const Vec3<T>& eb0, const Vec3<T>& eb1)
{
    return edge_edge_distance(ea0, ea1, eb0, eb1, edge_edge_distance_type(ea0, ea1, eb0, eb1));
}

/// @brief Gradient of edge_edge_distance for `type`. @param g out: 12 (d/dea0, d/dea1, d/deb0, d/deb1), m
template <class T>
DIFFIPC_HD inline void edge_edge_distance_gradient(
    const Vec3<T>& ea0, const Vec3<T>& ea1, const Vec3<T>& eb0, const Vec3<T>& eb1, EdgeEdgeDistanceType type, T* g)
{
    const Vec3<T>* v[4] = { &ea0, &ea1, &eb0, &eb1 };
    const edge_edge_detail::SubDistance sub = edge_edge_detail::sub_distance(type);
    T local[9];
    if (sub.kind == 0) {
        point_point_distance_gradient(*v[sub.ids[0]], *v[sub.ids[1]], local);
        distance_kernels::scatter_gradient<4, 2>(local, sub.ids, g);
    } else if (sub.kind == 1) {
        point_line_distance_gradient(*v[sub.ids[0]], *v[sub.ids[1]], *v[sub.ids[2]], local);
        distance_kernels::scatter_gradient<4, 3>(local, sub.ids, g);
    } else
        line_line_distance_gradient(ea0, ea1, eb0, eb1, g);
}

/// @brief Hessian of edge_edge_distance for `type`. @param H out: 12 x 12 row-major, ordered (ea0, ea1, eb0, eb1)
template <class T>
DIFFIPC_HD inline void edge_edge_distance_hessian(
    const Vec3<T>& ea0, const Vec3<T>& ea1, const Vec3<T>& eb0, const Vec3<T>& eb1, EdgeEdgeDistanceType type, T* H)
{
    const Vec3<T>* v[4] = { &ea0, &ea1, &eb0, &eb1 };
    const edge_edge_detail::SubDistance sub = edge_edge_detail::sub_distance(type);
    T local[81];
    if (sub.kind == 0) {
        point_point_distance_hessian(*v[sub.ids[0]], *v[sub.ids[1]], local);
        distance_kernels::scatter_hessian<4, 2>(local, sub.ids, H);
    } else if (sub.kind == 1) {
        point_line_distance_hessian(*v[sub.ids[0]], *v[sub.ids[1]], *v[sub.ids[2]], local);
        distance_kernels::scatter_hessian<4, 3>(local, sub.ids, H);
    } else
        line_line_distance_hessian(ea0, ea1, eb0, eb1, H);
}

} // namespace diffipc::kernels
