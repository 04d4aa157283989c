#pragma once
/// @file ccd.hpp
/// Conservative continuous collision detection (CCD) of primitive pairs moving
/// along linear trajectories: every vertex moves as x(t) = x_t0 + t (x_t1 - x_t0)
/// for t in [0, t_max] (t = 1 is the end of the step; the CCD only looks at
/// [0, t_max]).
///
/// Contract (all functions), with d(t) the exact Euclidean distance between the
/// primitives at time t in real arithmetic and dmin = settings.min_distance:
///  - collision == false: d(t) > dmin for all t in [0, t_max]. Never a false
///    negative, including exactly touching and degenerate configurations
///    (rounding is accounted for; see ccd.cpp).
///  - collision == true: toi in [0, t_max) and the motion is certified free up
///    to toi: d(t) > dmin on [0, toi], and at toi the gap d - dmin is at least
///    (1 - s) times the certified starting gap (s = conservative_rescaling; the
///    certified gap is the exact one less a round-off bound of about 1e-14 times
///    the coordinates' magnitude), so a barrier evaluated at toi stays finite.
///    toi == 0 means the start is already at or below dmin, or within round-off
///    of it (or max_iterations == 1); the caller should treat it as invalid.
///    A collision may be a false positive: plain ACCD reports one as soon as
///    the gap drops below (1 - s) times the starting gap (see
///    CCDSettings::refine), and any mode when the gap comes within round-off of
///    zero or the iteration budget runs out.
///  - budget_exhausted == true: the iteration budget ran out before a decision;
///    collision is true and toi is the time certified so far (before any
///    true impact), never "no collision".
///  - Non-finite coordinates give collision == true, toi = 0.
/// Invalid settings (min_distance < 0, conservative_rescaling outside (0, 1),
/// t_max < 0, max_iterations < 1, non-finite values) throw InputError.
///
/// Algorithm: Additive CCD (Li, Kaufman, Jiang 2021, "Codimensional Incremental
/// Potential Contact", Sec. 4 and Alg. 1), made rigorous in floating point by
/// certified distance lower bounds (distance_lower_bound.hpp) and bounds of the
/// trajectory's rounding. Point-plane CCD is analytic.
///
/// All positions are Eigen::Vector3d in metres; 2D callers set z = 0.

#include <Eigen/Core>

namespace diffipc {

struct CCDSettings {
    /// dmin (m): report a collision when the distance may reach this value (>= 0).
    double min_distance = 0;
    /// s in (0, 1): each ACCD step advances by s times the certified free time,
    /// and the search stops at the first time the gap falls below (1 - s) times
    /// the starting gap, which is the gap guaranteed at the returned toi.
    /// Larger s: fewer iterations, smaller gap left at toi.
    double conservative_rescaling = 0.9;
    /// Budget of distance evaluations per query (the initial one included).
    int max_iterations = 10000000;
    /// Only [0, t_max] of the trajectory is checked (t_max >= 0).
    double t_max = 1;
    /// Plain ACCD (false) reports a collision as soon as the gap falls below
    /// (1 - s) times the starting gap, so it also flags motions that only come
    /// close. With true, the search goes on from there (toi stays the last time
    /// with that gap) until it certifies [0, t_max] free (no collision) or the
    /// gap falls below refine_tolerance times the length of the relative motion,
    /// lp t_max (collision): fewer false positives for more iterations.
    bool refine = false;
    /// Relative gap below which a refined search reports a collision (> 0).
    double refine_tolerance = 1e-6;
};

struct CCDResult {
    /// True when an impact (distance <= dmin) could not be excluded on [0, t_max].
    bool collision = true;
    /// Certified free time when collision is true (see the contract above); t_max otherwise.
    double toi = 0;
    /// Distance evaluations used (ACCD) or 1 (analytic point-plane).
    int iterations = 0;
    /// The iteration budget ran out (collision is then true).
    bool budget_exhausted = false;
};

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
