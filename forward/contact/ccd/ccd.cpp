#include "forward/contact/ccd/ccd.hpp"

#include "forward/common/error.hpp"
#include "forward/contact/ccd/check_ccd_settings.hpp"
#include "forward/kernels/eigen_bridge.hpp"

namespace diffipc {

using kernels::to_vec3;

CCDResult point_triangle_ccd(const Eigen::Vector3d& p_t0, const Eigen::Vector3d& t0_t0, const Eigen::Vector3d& t1_t0,
    const Eigen::Vector3d& t2_t0, const Eigen::Vector3d& p_t1, const Eigen::Vector3d& t0_t1,
    const Eigen::Vector3d& t1_t1, const Eigen::Vector3d& t2_t1, const CCDSettings& settings)
{
    check_ccd_settings(settings);
    return kernels::point_triangle_ccd(to_vec3(p_t0), to_vec3(t0_t0), to_vec3(t1_t0), to_vec3(t2_t0), to_vec3(p_t1),
        to_vec3(t0_t1), to_vec3(t1_t1), to_vec3(t2_t1), settings);
}

CCDResult edge_edge_ccd(const Eigen::Vector3d& ea0_t0, const Eigen::Vector3d& ea1_t0, const Eigen::Vector3d& eb0_t0,
    const Eigen::Vector3d& eb1_t0, const Eigen::Vector3d& ea0_t1, const Eigen::Vector3d& ea1_t1,
    const Eigen::Vector3d& eb0_t1, const Eigen::Vector3d& eb1_t1, const CCDSettings& settings)
{
    check_ccd_settings(settings);
    return kernels::edge_edge_ccd(to_vec3(ea0_t0), to_vec3(ea1_t0), to_vec3(eb0_t0), to_vec3(eb1_t0), to_vec3(ea0_t1),
        to_vec3(ea1_t1), to_vec3(eb0_t1), to_vec3(eb1_t1), settings);
}

CCDResult point_edge_ccd(const Eigen::Vector3d& p_t0, const Eigen::Vector3d& e0_t0, const Eigen::Vector3d& e1_t0,
    const Eigen::Vector3d& p_t1, const Eigen::Vector3d& e0_t1, const Eigen::Vector3d& e1_t1,
    const CCDSettings& settings)
{
    check_ccd_settings(settings);
    return kernels::point_edge_ccd(
        to_vec3(p_t0), to_vec3(e0_t0), to_vec3(e1_t0), to_vec3(p_t1), to_vec3(e0_t1), to_vec3(e1_t1), settings);
}

CCDResult point_point_ccd(const Eigen::Vector3d& p0_t0, const Eigen::Vector3d& p1_t0, const Eigen::Vector3d& p0_t1,
    const Eigen::Vector3d& p1_t1, const CCDSettings& settings)
{
    check_ccd_settings(settings);
    return kernels::point_point_ccd(to_vec3(p0_t0), to_vec3(p1_t0), to_vec3(p0_t1), to_vec3(p1_t1), settings);
}

CCDResult point_plane_ccd(const Eigen::Vector3d& p_t0, const Eigen::Vector3d& p_t1,
    const Eigen::Vector3d& plane_origin_t0, const Eigen::Vector3d& plane_origin_t1, const Eigen::Vector3d& normal,
    const CCDSettings& settings)
{
    check_ccd_settings(settings);
    if (!normal.allFinite() || !(normal.squaredNorm() > 0))
        throw InputError("normal", "the plane normal must be finite and nonzero");
    return kernels::point_plane_ccd(
        to_vec3(p_t0), to_vec3(p_t1), to_vec3(plane_origin_t0), to_vec3(plane_origin_t1), to_vec3(normal), settings);
}

} // namespace diffipc
