#pragma once
/// @file distance_lower_bound.hpp
/// Certified lower bounds of (unsquared) distances between primitives, for the conservative CCD
/// (ccd.hpp), on the host and the device. Each function returns L with
///
///     0 <= L <= d(exact inputs),
///
/// d the exact Euclidean distance between the primitives spanned by the given double coordinates,
/// in real arithmetic, for coordinates' magnitudes between about 1e-60 and 1e60 (no underflow of
/// the products below, no overflow). L is also close to d: for well-shaped primitives d - L is a
/// few hundred units of round-off of the coordinates' differences (about 1e-14 relative); for
/// slivers and nearly parallel edges it grows towards the size of the sliver, which only costs
/// false positives in CCD. The proof model is IEEE 754 double arithmetic with round-to-nearest, no
/// -ffast-math; fused multiply-adds only shrink the errors. All functions take 3D points; 2D
/// callers set z = 0. NaN inputs give 0.
///
/// Error analysis, shared by all functions below. u = 2^-53 is the unit round-off. Differences of
/// inputs (e1 - e0, p - e0) are computed with a relative error u per component; a dot or cross
/// product of computed vectors x, y is within a few u |x| |y| of the exact one (at most 3u |x||y|
/// for a dot product, 2 sqrt(3) u |x||y| in norm for a cross product); a norm is within 3u
/// relative. Every bound below is the sum of such terms, derived line by line in the comments,
/// and then enlarged by a factor of 2 or more so that the proof does not hinge on the last ulp.
/// The bounds are small (hundreds of u times the size of the configuration); they matter only for
/// configurations that touch to within round-off, which the CCD then reports as collisions.
///
/// The CCD is not differentiated, so these are written on doubles, not over a scalar type.

#include "forward/kernels/vec3.hpp"

namespace diffipc::kernels {

namespace ccd_detail {

    /// Unit round-off 2^-53.
    constexpr double unit_roundoff = 0x1p-53;

    /// The distance from p to the segment as computed (an upper bound of the exact one up to
    /// round-off) and a bound of how much it can exceed the exact distance.
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
        // Any t in [0, 1] gives a point of the segment, so |w - t e| is an upper bound of the
        // exact distance; its excess over the exact distance is
        //  - the rounding of e and w, equivalent to moving p and e1 by u|w| and u|e| (the
        //    distance is 1-Lipschitz in each): u (|w| + |e|);
        //  - the error of t against the exact clamped projection, times |e|:
        //    (3u |w||e| / |e|^2 + 4u |w.e| / |e|^2) |e| <= 7u |w| (the clamp is 1-Lipschitz, and
        //    |w - t e| grows at most like |t - t*| |e|);
        //  - the rounding of w - t e and of its norm: 2u (|w| + |e|) + 3u (|w| + |e|).
        // Total 12u |w| + 6u |e|; we use 32u (|w| + |e|).
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

} // namespace ccd_detail

/// @brief Lower bound of |p0 - p1|.
DIFFIPC_HD inline double point_point_distance_lower_bound(const vec3& p0, const vec3& p1)
{
    // Rounding of the difference (u relative), of the sum of squares (3u) and of the square root
    // (u): 8u is a safe relative margin.
    return ccd_detail::clamp_nonnegative(norm(p0 - p1) * (1 - 8 * ccd_detail::unit_roundoff));
}

/// @brief Lower bound of the distance from point p to the segment (e0, e1) (a point if e0 == e1).
DIFFIPC_HD inline double point_edge_distance_lower_bound(const vec3& p, const vec3& e0, const vec3& e1)
{
    return ccd_detail::clamp_nonnegative(ccd_detail::lower(ccd_detail::point_segment(p, e0, e1)));
}

/// @brief Lower bound of the distance from point p to the triangle (t0, t1, t2) (any shape,
/// degenerate included).
DIFFIPC_HD inline double point_triangle_distance_lower_bound(
    const vec3& p, const vec3& t0, const vec3& t1, const vec3& t2)
{
    using namespace ccd_detail;
    const double u = unit_roundoff;
    // The closest point is either on the boundary, where the three point-edge bounds hold, or in
    // the interior, where the distance is the distance to the supporting plane. We never need to
    // know which one exactly:
    //  - if the projection of p onto the plane is certainly outside the triangle, the closest
    //    point is on the boundary (an interior closest point q has p - q normal to the plane, so
    //    q is the projection);
    //  - otherwise max(plane bound, boundary bound - r) is valid in both cases, where r >= the
    //    inradius |n| / perimeter bounds the distance from any interior point to the boundary.
    //    The plane bound is accurate for well-shaped triangles, the r term for slivers, whose
    //    normal is ill-determined but whose interior is within r of an edge.
    const vec3* v[3] = { &t0, &t1, &t2 };
    double lb_boundary = infinity<double>();
    double length[3];
    for (int i = 0; i < 3; ++i) {
        lb_boundary = min_of(lb_boundary, lower(point_segment(p, *v[i], *v[(i + 1) % 3])));
        length[i] = norm(*v[(i + 1) % 3] - *v[i]);
    }
    const double perimeter = length[0] + length[1] + length[2];
    if (!(perimeter > 0)) // all three corners coincide: the triangle is a point
        return clamp_nonnegative(lb_boundary);

    // Take the normal at the corner opposite the (first) longest edge: it minimizes |a||b| for
    // the same |a x b|, hence the relative error of the normal.
    int longest = 0;
    for (int i = 1; i < 3; ++i)
        if (length[longest] < length[i])
            longest = i;
    const int k = (longest + 2) % 3; // edge i = (v_i, v_i+1) is opposite corner i + 2
    const vec3 a = *v[(k + 1) % 3] - *v[k], b = *v[(k + 2) % 3] - *v[k], w = p - *v[k];
    const vec3 n = cross(a, b); // same orientation as (t1 - t0) x (t2 - t0)
    const double nn = norm(n), la = norm(a), lb = norm(b), lw = norm(w);
    // |n_computed - n_exact| <= (2u + 2 sqrt(3) u) |a||b| from the rounding of a, b and the cross product.
    const double n_error = 16 * u * la * lb;

    // Projection certainly outside: s_j = ((v_j+1 - v_j) x (p - v_j)) . n < 0 beyond its error,
    // |c||dn| + |n||dc| + 3u|c||n| <= |e_j||p - v_j| (6u |a||b| + 9u |n|).
    for (int j = 0; j < 3; ++j) {
        const vec3 pj = p - *v[j];
        const double s = dot(cross(*v[(j + 1) % 3] - *v[j], pj), n);
        if (s < -32 * u * length[j] * norm(pj) * (la * lb + nn))
            return clamp_nonnegative(lb_boundary);
    }

    // Plane: d = |w.n| / |n_exact| >= (|w.n|_computed - h_error) / (|n|_computed + n_error),
    // h_error = |w| |dn| + |dw||n| + 3u |w||n| <= |w| (6u |a||b| + 4u |n|).
    const double h_error = 16 * u * lw * (la * lb + nn);
    const double denominator = nn + n_error;
    const double lb_plane = denominator > 0 ? (fabs(dot(w, n)) - h_error) / denominator * (1 - 4 * u) : 0;
    const double inradius = (nn + n_error) / perimeter * (1 + 8 * u);
    return clamp_nonnegative(min_of(lb_boundary, max_of(lb_plane, lb_boundary - inradius)));
}

/// @brief Lower bound of the distance between the segments (ea0, ea1) and (eb0, eb1) (any
/// configuration: parallel, collinear, degenerate).
DIFFIPC_HD inline double edge_edge_distance_lower_bound(
    const vec3& ea0, const vec3& ea1, const vec3& eb0, const vec3& eb1)
{
    using namespace ccd_detail;
    const double u = unit_roundoff;
    // The minimum of |a(s) - b(t)| over [0,1]^2 is on the boundary of the square (an endpoint
    // against the other segment: four point-edge bounds) unless the unconstrained minimizer
    // (s*, t*) of the line-line problem is inside it. Then the distance is the line-line distance
    // |w.n| / |n|, n = ua x ub, and also at least (boundary distance - r): moving both closest
    // points along the edges (a by sigma ua, b by the same length along +-ub, whichever is within
    // 90 degrees) until one reaches an endpoint moves them apart by at most
    // min(|ua|,|ub|) 2 sin(theta/2) <= sqrt(2) |n| / max(|ua|, |ub|) =: r. The line-line bound is
    // accurate for crossing edges, the r term for nearly parallel ones.
    double lb_boundary = lower(point_segment(ea0, eb0, eb1)); // the first smallest of the four
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
    const double n_error = 16 * u * la * lb; // as for the triangle normal

    // s* = Ns / D, t* = Nt / D with D = |n|^2 (Binet-Cauchy identities:
    // Ns = (ua.ub)(ub.w) - (ub.ub)(ua.w) = n.(ub x w), Nt = (ua.ua)(ub.w) - (ua.ub)(ua.w) = n.(ua x w)).
    // Errors: |Ns| error <= |ub||w| (6u |ua||ub| + 9u |n|) (as the triangle's s_j),
    // |D| error <= |dn| (2|n| + |dn|) + 3u |n|^2. For exactly parallel edges (n = 0) none of the
    // "certainly outside" tests can fire.
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

} // namespace diffipc::kernels
