#include "forward/contact/distance/distance_type.hpp"

#include "forward/contact/distance/distance.hpp"

#include <Eigen/Geometry>

#include <limits>

namespace diffipc {

PointEdgeDistanceType point_edge_distance_type(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1)
{
    const Eigen::Vector3d e = e1 - e0;
    const double ee = e.squaredNorm();
    if (!(ee > 0))
        return PointEdgeDistanceType::P_E0;
    const double t = (p - e0).dot(e) / ee;
    if (t <= 0)
        return PointEdgeDistanceType::P_E0;
    if (t >= 1)
        return PointEdgeDistanceType::P_E1;
    return PointEdgeDistanceType::P_E;
}

PointTriangleDistanceType point_triangle_distance_type(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2)
{
    const Eigen::Vector3d n = (t1 - t0).cross(t2 - t0);
    const double nn = n.squaredNorm();
    // A sliver whose normal is lost in round-off is handled through its edges.
    if (nn > 1e-20 * (t1 - t0).squaredNorm() * (t2 - t0).squaredNorm()) {
        const bool inside = (t1 - t0).cross(p - t0).dot(n) >= 0 && (t2 - t1).cross(p - t1).dot(n) >= 0
            && (t0 - t2).cross(p - t2).dot(n) >= 0;
        if (inside)
            return PointTriangleDistanceType::P_T;
    }
    using PE = PointEdgeDistanceType;
    using PT = PointTriangleDistanceType;
    const Eigen::Vector3d* corners[3] = { &t0, &t1, &t2 };
    // Per edge i = (t_i, t_{i+1}): the type for its start, end and interior.
    const PT map[3][3] = { { PT::P_T0, PT::P_T1, PT::P_E0 }, { PT::P_T1, PT::P_T2, PT::P_E1 },
        { PT::P_T2, PT::P_T0, PT::P_E2 } };
    PT best = PT::P_T0;
    double best_distance = std::numeric_limits<double>::infinity();
    for (int i = 0; i < 3; ++i) {
        const Eigen::Vector3d& a = *corners[i];
        const Eigen::Vector3d& b = *corners[(i + 1) % 3];
        const PE type = point_edge_distance_type(p, a, b);
        const double dist = point_edge_distance(p, a, b, type);
        if (dist < best_distance) {
            best_distance = dist;
            best = map[i][int(type)];
        }
    }
    return best;
}

EdgeEdgeDistanceType edge_edge_distance_type(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    using EE = EdgeEdgeDistanceType;
    using PE = PointEdgeDistanceType;
    const Eigen::Vector3d u = ea1 - ea0, v = eb1 - eb0, w = ea0 - eb0;
    const double D = u.cross(v).squaredNorm();
    if (D > 0) {
        const double a = u.dot(u), b = u.dot(v), c = v.dot(v), d = u.dot(w), e = v.dot(w);
        const double s = (b * e - c * d) / D, t = (a * e - b * d) / D;
        if (s > 0 && s < 1 && t > 0 && t < 1)
            return EE::EA_EB;
    }
    // Boundary of [0,1]^2: one endpoint against the other segment.
    struct Candidate {
        const Eigen::Vector3d *p, *e0, *e1;
        EE types[3]; // for PE::P_E0, P_E1, P_E
    };
    const Candidate candidates[4] = {
        { &ea0, &eb0, &eb1, { EE::EA0_EB0, EE::EA0_EB1, EE::EA0_EB } },
        { &ea1, &eb0, &eb1, { EE::EA1_EB0, EE::EA1_EB1, EE::EA1_EB } },
        { &eb0, &ea0, &ea1, { EE::EA0_EB0, EE::EA1_EB0, EE::EA_EB0 } },
        { &eb1, &ea0, &ea1, { EE::EA0_EB1, EE::EA1_EB1, EE::EA_EB1 } },
    };
    EE best = EE::EA0_EB0;
    double best_distance = std::numeric_limits<double>::infinity();
    for (const Candidate& c : candidates) {
        const PE type = point_edge_distance_type(*c.p, *c.e0, *c.e1);
        const double dist = point_edge_distance(*c.p, *c.e0, *c.e1, type);
        if (dist < best_distance) {
            best_distance = dist;
            best = c.types[int(type)];
        }
    }
    return best;
}

} // namespace diffipc
