#pragma once
/// @file point_plane_ccd.cuh
/// CCD of a vertex against a half-space obstacle on host and device: the port of the CPU's point_plane_ccd
/// (forward/contact/ccd/ccd.cpp), which is analytic (the signed distance to a translating plane is linear in t).
/// Same operations in the same order as the CPU, so the same bits when compiled without fused multiply-adds
/// (see cuda/ccd/ccd.cuh); the step bound (step_bound.cu) needs it for the CPU's vertex-plane pairs. It lives
/// here rather than in cuda/ccd/ because the step bound is its only user so far.
///
/// Contract: the CPU's. With h(t) the signed distance of p(t) to the plane through o(t) with the given normal:
/// collision == false certifies |h(t)| > dmin on [0, t_max]; otherwise toi is certified free with a gap of at least
/// (1 - s) of the starting one; toi = 0 for an invalid start or non-finite coordinates.

#include "cuda/ccd/ccd.cuh"

namespace diffipc {
namespace gpu {

    /// @brief CCD of a point against a plane (through o with normal n) that both move linearly.
    /// @param p_t0, p_t1                          the point at t = 0 and t = 1 (m)
    /// @param plane_origin_t0, plane_origin_t1    the plane's point at t = 0 and t = 1 (m)
    /// @param normal                              finite and nonzero (any length; checked by the host caller)
    /// @param settings                            valid settings (check_ccd_settings); not checked here
    DIFFIPC_HD inline CCDResult point_plane_ccd(const vec3& p_t0, const vec3& p_t1, const vec3& plane_origin_t0,
        const vec3& plane_origin_t1, const vec3& normal, const CCDSettings& settings)
    {
        const double u = detail::unit_roundoff;
        CCDResult result;
        result.collision = true;
        result.toi = 0;
        result.iterations = 1;
        result.budget_exhausted = false;
        if (!all_finite(p_t0) || !all_finite(p_t1) || !all_finite(plane_origin_t0) || !all_finite(plane_origin_t1))
            return result;

        // h(t) = (p(t) - o(t)).n / |n| = h0 + t v; the rounding bounds are the CPU's (its comments give them).
        const double nn = norm(normal);
        const vec3 w = p_t0 - plane_origin_t0;
        const vec3 dp = p_t1 - p_t0, dorigin = plane_origin_t1 - plane_origin_t0;
        const vec3 dw = dp - dorigin;
        const double h0 = dot(w, normal) / nn, v = dot(dw, normal) / nn;
        const double h_error = 8 * u * norm(w);
        const double v_error = 8 * u * (norm(dp) + norm(dorigin) + norm(dw));
        const double d0 = fabs(h0) - h_error;
        const double gap0 = d0 - settings.min_distance - 4 * u * (fabs(d0) + settings.min_distance);
        if (!(gap0 > 0))
            return result;
        const double approach = (max_of(0.0, h0 > 0 ? -v : v) + v_error) * (1 + 4 * u);
        if (settings.t_max * approach * (1 + 2 * u) < gap0) {
            result.collision = false;
            result.toi = settings.t_max;
            return result;
        }
        result.toi = settings.conservative_rescaling * (gap0 / approach) * (1 - 4 * u);
        return result;
    }

} // namespace gpu
} // namespace diffipc
