#pragma once
/// @file distance_lower_bound.cuh
/// Certified lower bounds of (unsquared) distances between primitives, for the
/// GPU CCD: the port of forward/contact/ccd/distance_lower_bound.{hpp,cpp} to
/// __host__ __device__ code on vec3. Same contract: each function returns L with
///
///     0 <= L <= d(exact inputs),
///
/// d the exact Euclidean distance between the primitives spanned by the given
/// double coordinates, in real arithmetic, for coordinates' magnitudes between
/// about 1e-60 and 1e60. The error analysis is the CPU file's, line by line
/// (its comments are the proof; the steps here are the same operations in the
/// same order, so each bound rounds alike and L is the CPU's L bit for bit when
/// the device code is compiled without fused multiply-adds, see ccd.cuh).
/// All functions take 3D points; 2D callers set z = 0.

#include "cuda/common/kernels.cuh"

namespace diffipc {
namespace gpu {

    namespace detail {

        /// Unit round-off 2^-53.
        constexpr double unit_roundoff = 0x1p-53;

        /// The distance from p to the segment as computed (an upper bound of the
        /// exact one up to round-off) and a bound of how much it can exceed it.
        struct Estimate {
            double value;
            double error;
        };

        DIFFIPC_HD inline Estimate point_segment(const vec3& p, const vec3& e0, const vec3& e1)
        {
            const double u = unit_roundoff;
            const vec3 e = e1 - e0, w = p - e0;
            const double ee = squared_norm(e);
            double t = 0;
            if (ee > 0) {
                t = dot(w, e) / ee;
                t = t > 0 ? (t < 1 ? t : 1) : 0; // also maps NaN to 0
            }
            // Excess over the exact distance: 12u |w| + 6u |e| (see the CPU file); we use 32u (|w| + |e|).
            Estimate estimate;
            estimate.value = norm(w - t * e);
            estimate.error = 32 * u * (norm(w) + sqrt(ee));
            if (!(ee > 0)) // an edge so short that |e|^2 underflowed: we measured |p - e0|
                estimate.error += sqrt(3.0) * max_abs(e);
            return estimate;
        }

        DIFFIPC_HD inline double lower(const Estimate& e) { return e.value - e.error; }

        /// NaN -> 0: never claims a distance.
        DIFFIPC_HD inline double clamp_nonnegative(double x) { return x > 0 ? x : 0; }

    } // namespace detail

    /// @brief Lower bound of |p0 - p1|.
    DIFFIPC_HD inline double point_point_distance_lower_bound(const vec3& p0, const vec3& p1)
    {
        // Rounding of the difference (u relative), of the sum of squares (3u) and of the square root (u).
        return detail::clamp_nonnegative(norm(p0 - p1) * (1 - 8 * detail::unit_roundoff));
    }

    /// @brief Lower bound of the distance from point p to the segment (e0, e1) (a point if e0 == e1).
    DIFFIPC_HD inline double point_edge_distance_lower_bound(const vec3& p, const vec3& e0, const vec3& e1)
    {
        return detail::clamp_nonnegative(detail::lower(detail::point_segment(p, e0, e1)));
    }

    /// @brief Lower bound of the distance from point p to the triangle (t0, t1, t2) (any shape, degenerate included).
    /// The closest point is on the boundary (three point-edge bounds) or in the interior (the plane bound);
    /// where the projection is not certainly outside, max(plane bound, boundary bound - inradius bound) holds
    /// in both cases (see the CPU file).
    DIFFIPC_HD inline double point_triangle_distance_lower_bound(
        const vec3& p, const vec3& t0, const vec3& t1, const vec3& t2)
    {
        using namespace detail;
        const double u = unit_roundoff;
        const vec3* v[3] = { &t0, &t1, &t2 };
        double lb_boundary = INFINITY;
        double length[3];
        for (int i = 0; i < 3; ++i) {
            lb_boundary = min_of(lb_boundary, lower(point_segment(p, *v[i], *v[(i + 1) % 3])));
            length[i] = norm(*v[(i + 1) % 3] - *v[i]);
        }
        const double perimeter = length[0] + length[1] + length[2];
        if (!(perimeter > 0)) // all three corners coincide: the triangle is a point
            return clamp_nonnegative(lb_boundary);

        // The normal at the corner opposite the longest edge (the first longest, as std::max_element).
        int longest = 0;
        for (int i = 1; i < 3; ++i)
            if (length[longest] < length[i])
                longest = i;
        const int k = (longest + 2) % 3; // edge i = (v_i, v_i+1) is opposite corner i + 2
        const vec3 a = *v[(k + 1) % 3] - *v[k], b = *v[(k + 2) % 3] - *v[k], w = p - *v[k];
        const vec3 n = cross(a, b);
        const double nn = norm(n), la = norm(a), lb = norm(b), lw = norm(w);
        const double n_error = 16 * u * la * lb;

        // Projection certainly outside the triangle: the closest point is on the boundary.
        for (int j = 0; j < 3; ++j) {
            const vec3 pj = p - *v[j];
            const double s = dot(cross(*v[(j + 1) % 3] - *v[j], pj), n);
            if (s < -32 * u * length[j] * norm(pj) * (la * lb + nn))
                return clamp_nonnegative(lb_boundary);
        }

        const double h_error = 16 * u * lw * (la * lb + nn);
        const double denominator = nn + n_error;
        const double lb_plane = denominator > 0 ? (fabs(dot(w, n)) - h_error) / denominator * (1 - 4 * u) : 0;
        const double inradius = (nn + n_error) / perimeter * (1 + 8 * u);
        return clamp_nonnegative(min_of(lb_boundary, max_of(lb_plane, lb_boundary - inradius)));
    }

    /// @brief Lower bound of the distance between the segments (ea0, ea1) and (eb0, eb1) (any configuration:
    /// parallel, collinear, degenerate). Boundary (four point-edge bounds) unless the line-line minimizer may be
    /// inside; then max(line-line bound, boundary bound - r) (see the CPU file).
    DIFFIPC_HD inline double edge_edge_distance_lower_bound(
        const vec3& ea0, const vec3& ea1, const vec3& eb0, const vec3& eb1)
    {
        using namespace detail;
        const double u = unit_roundoff;
        // std::min({ a, b, c, d }): the first smallest.
        double lb_boundary = lower(point_segment(ea0, eb0, eb1));
        lb_boundary = min_of(lb_boundary, lower(point_segment(ea1, eb0, eb1)));
        lb_boundary = min_of(lb_boundary, lower(point_segment(eb0, ea0, ea1)));
        lb_boundary = min_of(lb_boundary, lower(point_segment(eb1, ea0, ea1)));
        const vec3 ua = ea1 - ea0, ub = eb1 - eb0, w = ea0 - eb0;
        const double la = norm(ua), lb = norm(ub), lw = norm(w);
        const double lmax = max_of(la, lb);
        if (!(lmax > 0)) // both edges are points
            return clamp_nonnegative(lb_boundary);
        const vec3 n = cross(ua, ub);
        const double nn = norm(n);
        const double n_error = 16 * u * la * lb;

        // s* = Ns / D, t* = Nt / D, D = |n|^2 (Binet-Cauchy), with their rounding bounds.
        const double D = dot(n, n);
        const double D_error = 2 * n_error * (nn + n_error) + 4 * u * nn * nn;
        const double Ns = dot(n, cross(ub, w)), Nt = dot(n, cross(ua, w));
        const double Ns_error = 32 * u * lb * lw * (la * lb + nn), Nt_error = 32 * u * la * lw * (la * lb + nn);
        if (Ns < -Ns_error || Ns > D + D_error + Ns_error || Nt < -Nt_error || Nt > D + D_error + Nt_error)
            return clamp_nonnegative(lb_boundary);

        const double h_error = 16 * u * lw * (la * lb + nn);
        const double denominator = nn + n_error;
        const double lb_line = denominator > 0 ? (fabs(dot(w, n)) - h_error) / denominator * (1 - 4 * u) : 0;
        const double r = 1.5 * (nn + n_error) / lmax * (1 + 8 * u); // 1.5 > sqrt(2) absorbs the rounding of r
        return clamp_nonnegative(min_of(lb_boundary, max_of(lb_line, lb_boundary - r)));
    }

} // namespace gpu
} // namespace diffipc
