#pragma once
/// @file ccd.hpp
/// Conservative continuous collision detection (CCD) of primitive pairs moving along linear
/// trajectories, for the CPU path: Eigen arguments and checked settings around the one CCD that
/// both paths run (forward/kernels/ccd/ccd.hpp, which states the contract and the algorithm:
/// Additive CCD with certified distance lower bounds; point-plane in closed form).
/// Invalid settings (min_distance < 0, conservative_rescaling outside (0, 1), t_max < 0,
/// max_iterations < 1, non-finite values) throw InputError.
///
/// All positions are Eigen::Vector3d in metres; 2D callers set z = 0.

#include "forward/kernels/ccd/ccd.hpp"

#include <Eigen/Core>

namespace diffipc {

// One type per concept, shared with the GPU path.
using kernels::CCDResult;
using kernels::CCDSettings;

/// @brief CCD of a point against a triangle.
/// @param p_t0, t0_t0, t1_t0, t2_t0  point and triangle corners at t = 0 (m)
/// @param p_t1, t0_t1, t1_t1, t2_t1  the same at t = 1 (m)
/// @return see the contract in the file comment
CCDResult point_triangle_ccd(const Eigen::Vector3d& p_t0, const Eigen::Vector3d& t0_t0, const Eigen::Vector3d& t1_t0,
    const Eigen::Vector3d& t2_t0, const Eigen::Vector3d& p_t1, const Eigen::Vector3d& t0_t1,
    const Eigen::Vector3d& t1_t1, const Eigen::Vector3d& t2_t1, const CCDSettings& settings = {});

/// @brief CCD of two segments (ea0, ea1) and (eb0, eb1).
/// @param ea0_t0, ea1_t0, eb0_t0, eb1_t0  edge endpoints at t = 0 (m)
/// @param ea0_t1, ea1_t1, eb0_t1, eb1_t1  the same at t = 1 (m)
CCDResult edge_edge_ccd(const Eigen::Vector3d& ea0_t0, const Eigen::Vector3d& ea1_t0, const Eigen::Vector3d& eb0_t0,
    const Eigen::Vector3d& eb1_t0, const Eigen::Vector3d& ea0_t1, const Eigen::Vector3d& ea1_t1,
    const Eigen::Vector3d& eb0_t1, const Eigen::Vector3d& eb1_t1, const CCDSettings& settings = {});

/// @brief CCD of a point against a segment (e0, e1), in 3D or in 2D (z = 0).
/// @param p_t0, e0_t0, e1_t0  point and segment endpoints at t = 0 (m)
/// @param p_t1, e0_t1, e1_t1  the same at t = 1 (m)
CCDResult point_edge_ccd(const Eigen::Vector3d& p_t0, const Eigen::Vector3d& e0_t0, const Eigen::Vector3d& e1_t0,
    const Eigen::Vector3d& p_t1, const Eigen::Vector3d& e0_t1, const Eigen::Vector3d& e1_t1,
    const CCDSettings& settings = {});

/// @brief CCD of two points.
/// @param p0_t0, p1_t0  the points at t = 0 (m)
/// @param p0_t1, p1_t1  the points at t = 1 (m)
CCDResult point_point_ccd(const Eigen::Vector3d& p0_t0, const Eigen::Vector3d& p1_t0, const Eigen::Vector3d& p0_t1,
    const Eigen::Vector3d& p1_t1, const CCDSettings& settings = {});

/// @brief CCD of a point against an infinite plane that translates with its
/// origin and keeps its normal. The distance is the unsigned |(p - o) . n| / |n|;
/// it is linear in t on each side, so the first time it reaches dmin is found in
/// closed form (no iterations; conservative_rescaling and max_iterations only set
/// the returned toi = s times that time, so that the gap at toi is (1 - s) times
/// the starting gap).
/// @param p_t0, p_t1                        the point at t = 0 and t = 1 (m)
/// @param plane_origin_t0, plane_origin_t1  a point of the plane at t = 0 and t = 1 (m)
/// @param normal                            plane normal, any nonzero length
CCDResult point_plane_ccd(const Eigen::Vector3d& p_t0, const Eigen::Vector3d& p_t1,
    const Eigen::Vector3d& plane_origin_t0, const Eigen::Vector3d& plane_origin_t1, const Eigen::Vector3d& normal,
    const CCDSettings& settings = {});

} // namespace diffipc
