#include "forward/contact/distance/distance_type.hpp"

#include "forward/kernels/eigen_bridge.hpp"

namespace diffipc {

using kernels::to_vec3;

PointEdgeDistanceType point_edge_distance_type(
    const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1)
{
    return kernels::point_edge_distance_type(to_vec3(p), to_vec3(e0), to_vec3(e1));
}

PointTriangleDistanceType point_triangle_distance_type(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2)
{
    return kernels::point_triangle_distance_type(to_vec3(p), to_vec3(t0), to_vec3(t1), to_vec3(t2));
}

EdgeEdgeDistanceType edge_edge_distance_type(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    return kernels::edge_edge_distance_type(to_vec3(ea0), to_vec3(ea1), to_vec3(eb0), to_vec3(eb1));
}

} // namespace diffipc
