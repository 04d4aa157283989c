#pragma once
/// @file distance_type.hpp
/// Which pair of closest features realizes the distance between two primitives. The squared
/// distance of a primitive pair is the squared distance of that feature pair (point-point,
/// point-line, point-plane or line-line), so each type picks a smooth formula and its
/// derivatives. The classification handles the degenerate sub-cases (zero-length edges, slivers,
/// parallel edges). Contact::distance_type stores the enumerators as int. Edges of a triangle:
/// E0 = (t0, t1), E1 = (t1, t2), E2 = (t2, t0).

#include "forward/kernels/distance/point_line.hpp"
#include "forward/kernels/distance/point_point.hpp"

namespace diffipc::kernels {

enum class PointEdgeDistanceType : int {
    P_E0, ///< closest to e0
    P_E1, ///< closest to e1
    P_E, ///< closest to the edge's interior (point-line)
};

enum class PointTriangleDistanceType : int {
    P_T0,
    P_T1,
    P_T2,
    P_E0, ///< point-line to (t0, t1)
    P_E1, ///< point-line to (t1, t2)
    P_E2, ///< point-line to (t2, t0)
    P_T, ///< point-plane
};

enum class EdgeEdgeDistanceType : int {
    EA0_EB0,
    EA0_EB1,
    EA1_EB0,
    EA1_EB1,
    EA_EB0, ///< eb0 to line a
    EA_EB1, ///< eb1 to line a
    EA0_EB, ///< ea0 to line b
    EA1_EB, ///< ea1 to line b
    EA_EB, ///< line-line
};

namespace distance_type_detail {
    /// point_edge_distance (point_edge.hpp) for a given type, needed here for the classification.
    template <class T>
    DIFFIPC_HD inline T point_edge_distance(
        const Vec3<T>& p, const Vec3<T>& e0, const Vec3<T>& e1, PointEdgeDistanceType t)
    {
        switch (t) {
        case PointEdgeDistanceType::P_E0:
            return point_point_distance(p, e0);
        case PointEdgeDistanceType::P_E1:
            return point_point_distance(p, e1);
        case PointEdgeDistanceType::P_E:
            return point_line_distance(p, e0, e1);
        }
        return 0;
    }
} // namespace distance_type_detail

/// @brief Closest-feature type of point p to segment (e0, e1), 2D (z = 0) or 3D. A degenerate
/// edge gives P_E0.
template <class T>
DIFFIPC_HD inline PointEdgeDistanceType point_edge_distance_type(const Vec3<T>& p, const Vec3<T>& e0, const Vec3<T>& e1)
{
    const Vec3<T> e = e1 - e0;
    const T ee = squared_norm(e);
    if (!(ee > 0))
        return PointEdgeDistanceType::P_E0;
    const T t = dot(p - e0, e) / ee;
    if (t <= 0)
        return PointEdgeDistanceType::P_E0;
    if (t >= 1)
        return PointEdgeDistanceType::P_E1;
    return PointEdgeDistanceType::P_E;
}

/// @brief Closest-feature type of point p to triangle (t0, t1, t2): the plane type only when the
/// projection of p falls inside the triangle, otherwise the closest of the three edges decides;
/// a sliver whose normal is lost in round-off is treated through its edges.
template <class T>
DIFFIPC_HD inline PointTriangleDistanceType point_triangle_distance_type(
    const Vec3<T>& p, const Vec3<T>& t0, const Vec3<T>& t1, const Vec3<T>& t2)
{
    using PE = PointEdgeDistanceType;
    using PT = PointTriangleDistanceType;
    const Vec3<T> n = cross(t1 - t0, t2 - t0);
    const T nn = squared_norm(n);
    if (nn > 1e-20 * squared_norm(t1 - t0) * squared_norm(t2 - t0)) {
        const bool inside = dot(cross(t1 - t0, p - t0), n) >= 0 && dot(cross(t2 - t1, p - t1), n) >= 0
            && dot(cross(t0 - t2, p - t2), n) >= 0;
        if (inside)
            return PT::P_T;
    }
    const Vec3<T>* corners[3] = { &t0, &t1, &t2 };
    // Per edge i = (t_i, t_{i+1}): the type for its start, end and interior.
    const PT map[3][3]
        = { { PT::P_T0, PT::P_T1, PT::P_E0 }, { PT::P_T1, PT::P_T2, PT::P_E1 }, { PT::P_T2, PT::P_T0, PT::P_E2 } };
    PT best = PT::P_T0;
    T best_distance = infinity<T>();
    for (int i = 0; i < 3; ++i) {
        const Vec3<T>& a = *corners[i];
        const Vec3<T>& b = *corners[(i + 1) % 3];
        const PE type = point_edge_distance_type(p, a, b);
        const T dist = distance_type_detail::point_edge_distance(p, a, b, type);
        if (dist < best_distance) {
            best_distance = dist;
            best = map[i][int(type)];
        }
    }
    return best;
}

/// @brief Closest-feature type of segments (ea0, ea1) and (eb0, eb1): the interior critical point
/// of the line-line distance (non-parallel lines only) if it lies inside both edges, otherwise
/// the closest of the four endpoint-against-segment candidates (no parallelism threshold).
template <class T>
DIFFIPC_HD inline EdgeEdgeDistanceType edge_edge_distance_type(
    const Vec3<T>& ea0, const Vec3<T>& ea1, const Vec3<T>& eb0, const Vec3<T>& eb1)
{
    using EE = EdgeEdgeDistanceType;
    using PE = PointEdgeDistanceType;
    const Vec3<T> u = ea1 - ea0, v = eb1 - eb0, w = ea0 - eb0;
    const T D = squared_norm(cross(u, v));
    if (D > 0) {
        const T a = dot(u, u), b = dot(u, v), c = dot(v, v), d = dot(u, w), e = dot(v, w);
        const T s = (b * e - c * d) / D, t = (a * e - b * d) / D;
        if (s > 0 && s < 1 && t > 0 && t < 1)
            return EE::EA_EB;
    }
    // Boundary of [0,1]^2: one endpoint against the other segment.
    const Vec3<T>* points[4] = { &ea0, &ea1, &eb0, &eb1 };
    const Vec3<T>* edge0[4] = { &eb0, &eb0, &ea0, &ea0 };
    const Vec3<T>* edge1[4] = { &eb1, &eb1, &ea1, &ea1 };
    const EE types[4][3] = { { EE::EA0_EB0, EE::EA0_EB1, EE::EA0_EB }, { EE::EA1_EB0, EE::EA1_EB1, EE::EA1_EB },
        { EE::EA0_EB0, EE::EA1_EB0, EE::EA_EB0 }, { EE::EA0_EB1, EE::EA1_EB1, EE::EA_EB1 } };
    EE best = EE::EA0_EB0;
    T best_distance = infinity<T>();
    for (int k = 0; k < 4; ++k) {
        const PE type = point_edge_distance_type(*points[k], *edge0[k], *edge1[k]);
        const T dist = distance_type_detail::point_edge_distance(*points[k], *edge0[k], *edge1[k], type);
        if (dist < best_distance) {
            best_distance = dist;
            best = types[k][int(type)];
        }
    }
    return best;
}

} // namespace diffipc::kernels
