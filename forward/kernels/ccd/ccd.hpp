#pragma once
/// @file ccd.hpp
/// Conservative continuous collision detection (CCD) of one primitive pair moving along linear
/// trajectories, on the host and the device: every vertex moves as x(t) = x_t0 + t (x_t1 - x_t0)
/// for t in [0, t_max] (t = 1 is the end of the step; the CCD only looks at [0, t_max]). The CPU
/// path calls it through forward/contact/ccd/ccd.hpp (Eigen arguments, settings checked), the GPU
/// path from its kernels (cuda/ccd/ccd.cu one thread per query, cuda/broad_phase/step_bound.cu).
///
/// Contract (all functions), with d(t) the exact Euclidean distance between the primitives at time
/// t in real arithmetic and dmin = settings.min_distance:
///  - collision == false: d(t) > dmin for all t in [0, t_max]. Never a false negative, including
///    exactly touching and degenerate configurations (rounding is accounted for; see
///    additive_ccd).
///  - collision == true: toi in [0, t_max) and the motion is certified free up to toi: d(t) > dmin
///    on [0, toi], and at toi the gap d - dmin is at least (1 - s) times the certified starting
///    gap (s = conservative_rescaling; the certified gap is the exact one less a round-off bound
///    of about 1e-14 times the coordinates' magnitude), so a barrier evaluated at toi stays
///    finite. toi == 0 means the start is already at or below dmin, or within round-off of it (or
///    max_iterations == 1); the caller should treat it as invalid. A collision may be a false
///    positive: plain ACCD reports one as soon as the gap drops below (1 - s) times the starting
///    gap (see CCDSettings::refine), and any mode when the gap comes within round-off of zero or
///    the iteration budget runs out.
///  - budget_exhausted == true: the iteration budget ran out before a decision; collision is true
///    and toi is the time certified so far (before any true impact), never "no collision".
///  - Non-finite coordinates give collision == true, toi = 0.
/// Settings are not checked here (no exceptions on the device): check_ccd_settings
/// (forward/contact/ccd/check_ccd_settings.hpp) does it on the host; invalid values never give
/// "no collision" for an impact but are not errors here.
///
/// Algorithm: Additive CCD (Li, Kaufman, Jiang 2021, "Codimensional Incremental Potential
/// Contact", Sec. 4 and Alg. 1), made rigorous in floating point by certified distance lower
/// bounds (distance_lower_bound.hpp) and bounds of the trajectory's rounding. Point-plane CCD is
/// analytic.
///
/// Same results on both sides, bit for bit: IEEE 754 double +, -, *, / and sqrt are correctly
/// rounded on the host and the device (nvcc's defaults -prec-div=true, -prec-sqrt=true, no
/// -use_fast_math; double subnormals are never flushed on the GPU). What a compiler would change
/// is the contraction of a * b + c into a fused multiply-add, which nvcc does by default on the
/// device: the .cu files that call these functions are compiled with -fmad=false, and the host
/// side as this repo builds it (g++ -O2 on x86-64 without -march, so no FMA instructions) never
/// contracts. tests/cuda/ccd/test_ccd.cpp checks the GPU's results against the host's on the
/// sample queries under several settings. It matters: with contraction allowed the toi and
/// iterations of 1 to 6% of the sample queries differ (their collision flags did not); with FMA
/// the results are still conservative (fused operations only shrink the rounding errors the
/// bounds allow for), but no longer bitwise equal.
///
/// The CCD is not differentiated, so it is written on doubles, not over a scalar type. Positions
/// are in metres; 2D callers set z = 0.

#include "forward/kernels/ccd/distance_lower_bound.hpp"

namespace diffipc::kernels {

struct CCDSettings {
    /// dmin (m): report a collision when the distance may reach this value (>= 0).
    double min_distance = 0;
    /// s in (0, 1): each ACCD step advances by s times the certified free time, and the search
    /// stops at the first time the gap falls below (1 - s) times the starting gap, which is the
    /// gap guaranteed at the returned toi. Larger s: fewer iterations, smaller gap left at toi.
    double conservative_rescaling = 0.9;
    /// Budget of distance evaluations per query (the initial one included).
    int max_iterations = 10000000;
    /// Only [0, t_max] of the trajectory is checked (t_max >= 0).
    double t_max = 1;
    /// Plain ACCD (false) reports a collision as soon as the gap falls below (1 - s) times the
    /// starting gap, so it also flags motions that only come close. With true, the search goes on
    /// from there (toi stays the last time with that gap) until it certifies [0, t_max] free (no
    /// collision) or the gap falls below refine_tolerance times the length of the relative
    /// motion, lp t_max (collision): fewer false positives for more iterations.
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

/// The primitive pairs, and the vertex order of a query of each kind.
enum class CCDKind : int {
    POINT_TRIANGLE = 0, ///< p, t0, t1, t2
    EDGE_EDGE = 1, ///< ea0, ea1, eb0, eb1
    POINT_EDGE = 2, ///< p, e0, e1 (3D, or 2D with z = 0)
    POINT_POINT = 3, ///< p0, p1
};

/// Vertices of one primitive pair (4, 4, 3, 2); a query holds twice as many positions (t = 0, then t = 1).
DIFFIPC_HD inline int ccd_vertex_count(CCDKind kind)
{
    return kind == CCDKind::POINT_TRIANGLE || kind == CCDKind::EDGE_EDGE ? 4 : kind == CCDKind::POINT_EDGE ? 3 : 2;
}

namespace ccd_detail {

    /// The certified gap at time t: lower bound of the distance at the computed positions, less
    /// the trajectory's rounding tau and dmin, less the rounding of these subtractions.
    template <int N, typename LowerBound>
    DIFFIPC_HD double certified_gap(
        const vec3 (&x_t0)[N], const vec3 (&v)[N], double t, const LowerBound& lower_bound, double tau, double dmin)
    {
        const double u = unit_roundoff;
        vec3 x[N];
        for (int i = 0; i < N; ++i)
            x[i] = x_t0[i] + t * v[i];
        const double d = lower_bound(x);
        return d - tau - dmin - 4 * u * (d + tau + dmin);
    }

    /// Additive CCD (Li, Kaufman, Jiang 2021, Alg. 1) on N vertices, the first n_first of which
    /// form one primitive and the rest the other. lower_bound(x) returns a certified lower bound
    /// of the distance between the primitives with vertex positions x (distance_lower_bound.hpp).
    ///
    /// Why it is conservative in floating point:
    ///  1. The exact trajectory X_i(t) = x_i,t0 + t (x_i,t1 - x_i,t0), shifted by -t m for the
    ///     mean displacement m (a common translation, so distances are unchanged), is evaluated
    ///     as fl(x_i,t0 + fl(t v_i)) with v_i = fl(fl(x_i,t1 - x_i,t0) - m). Per component the
    ///     computed position is within u (t_max (|dx_i| + 2 |v_i|) + |x_i|) of the exact one; a
    ///     distance moves by at most the largest displacement of each primitive's vertices, so
    ///     gap(t) = lower_bound(computed x) - tau - dmin with tau = 2 sqrt(3) u max_i(...) (we use
    ///     8 u) bounds the exact gap from below.
    ///  2. The exact distance is Lipschitz in t with constant lp = max_{i in A, j in B} |v_i - v_j|,
    ///     enlarged for the rounding of v: d(t) = min over barycentric weights (a, b) of
    ///     |sum a_i x_i(t) - sum b_j x_j(t)|, each of these functions has slope at most
    ///     |sum a_i v_i - sum b_j v_j|, a convex function of (a, b) whose maximum is at a vertex
    ///     pair, and a minimum of lp-Lipschitz functions is lp-Lipschitz. This is never larger
    ///     than ACCD's max_A |v_i| + max_B |v_j| (with the mean removed) and smaller for rotating
    ///     primitives. So a certified gap g at t certifies [t, t + g / lp], and g - lp (t' - t)
    ///     bounds the gap at t'.
    ///  3. Each step goes s g / lp, s < 1; the slack (1 - s) g / lp absorbs the rounding of
    ///     t + dt as long as dt >= min_step = 16 u t_max / (1 - s). A smaller step means the gap
    ///     is within ~1e-14 (relative to the motion) of zero, i.e. a touching contact up to
    ///     round-off: we stop and report a collision at the current certified time instead of
    ///     stalling (this is the safeguard for exactly touching configurations: a true distance
    ///     of zero can never be stepped over, its lower bound is <= 0 there and the step sizes
    ///     shrink to zero before it).
    ///  4. Every comparison is written so that NaN leads to "collision".
    template <int N, typename LowerBound>
    DIFFIPC_HD CCDResult additive_ccd(const vec3 (&x_t0)[N], const vec3 (&x_t1)[N], int n_first,
        const LowerBound& lower_bound, const CCDSettings& settings)
    {
        const double u = unit_roundoff;
        CCDResult result;
        result.collision = true;
        result.toi = 0;
        result.iterations = 0;
        result.budget_exhausted = false;
        for (int i = 0; i < N; ++i)
            if (!all_finite(x_t0[i]) || !all_finite(x_t1[i]))
                return result;

        const double t_max = settings.t_max, dmin = settings.min_distance, s = settings.conservative_rescaling;
        vec3 v[N];
        vec3 mean(0, 0, 0);
        for (int i = 0; i < N; ++i) {
            v[i] = x_t1[i] - x_t0[i];
            mean = mean + v[i];
        }
        mean = mean / double(N);
        double position_scale = 0, velocity_scale = 0;
        for (int i = 0; i < N; ++i) {
            const double dx = max_abs(v[i]);
            v[i] = v[i] - mean;
            const double vi = max_abs(v[i]);
            const double xi = max_of(max_abs(x_t0[i]), max_abs(x_t0[i] + t_max * v[i]));
            position_scale = max_of(position_scale, t_max * (dx + 2 * vi) + xi);
            velocity_scale = max_of(velocity_scale, dx + vi);
        }
        double relative_speed = 0;
        for (int i = 0; i < n_first; ++i)
            for (int j = n_first; j < N; ++j)
                relative_speed = max_of(relative_speed, norm(v[i] - v[j]));
        // |v_exact - v_computed| <= sqrt(3) u (|dx| + |v|) per vertex, twice for a difference;
        // the difference and its norm round by 4u relative.
        const double lp = (relative_speed + 8 * u * velocity_scale) * (1 + 8 * u);
        const double tau = 8 * u * position_scale;

        result.iterations = 1;
        const double gap0 = certified_gap<N>(x_t0, v, 0, lower_bound, tau, dmin);
        if (!(gap0 > 0))
            return result; // starts at or below dmin (up to round-off)
        if (!(lp > 0)) { // rigid translation: the distance is constant
            result.collision = false;
            result.toi = t_max;
            return result;
        }
        const double gap_stop = (1 - s) * gap0;
        // A refined search only decides "collision" below this gap; toi stays the first time the
        // gap fell below gap_stop.
        const double gap_collision
            = settings.refine ? min_of(gap_stop, settings.refine_tolerance * lp * t_max) : gap_stop;
        const double min_step = 16 * u * t_max / (1 - s);
        double t = 0, gap = gap0, toi = -1;
        while (true) {
            const double dt = s * (gap / lp) * (1 - 4 * u);
            if (!(dt >= min_step))
                break; // gap within round-off of zero: collision at t
            const double t_next = t + dt;
            if (t_next >= t_max) { // [t, t_max] is certified free
                result.collision = false;
                result.toi = t_max;
                return result;
            }
            if (result.iterations >= settings.max_iterations) {
                result.budget_exhausted = true;
                break;
            }
            ++result.iterations;
            // Two certified lower bounds of the gap at t_next: the evaluated one and the Lipschitz
            // one; the latter guarantees (1 - s) gap after a step.
            const double propagated = gap - lp * (t_next - t) * (1 + 4 * u) - 2 * u * gap;
            const double evaluated = certified_gap<N>(x_t0, v, t_next, lower_bound, tau, dmin);
            const double gap_next = evaluated > propagated ? evaluated : propagated;
            // The first step is always taken (Alg. 1's "t > 0"): its gap is at least (1 - s) gap0
            // by the Lipschitz bound, so toi = 0 only for invalid starts.
            if (t > 0 && !(gap_next >= gap_stop) && toi < 0)
                toi = t;
            if (t > 0 && !(gap_next >= gap_collision))
                break;
            t = t_next;
            gap = gap_next;
        }
        result.toi = toi >= 0 ? toi : t;
        return result;
    }

    struct PointTriangleLowerBound {
        DIFFIPC_HD double operator()(const vec3 (&x)[4]) const
        {
            return point_triangle_distance_lower_bound(x[0], x[1], x[2], x[3]);
        }
    };
    struct EdgeEdgeLowerBound {
        DIFFIPC_HD double operator()(const vec3 (&x)[4]) const
        {
            return edge_edge_distance_lower_bound(x[0], x[1], x[2], x[3]);
        }
    };
    struct PointEdgeLowerBound {
        DIFFIPC_HD double operator()(const vec3 (&x)[3]) const
        {
            return point_edge_distance_lower_bound(x[0], x[1], x[2]);
        }
    };
    struct PointPointLowerBound {
        DIFFIPC_HD double operator()(const vec3 (&x)[2]) const { return point_point_distance_lower_bound(x[0], x[1]); }
    };

} // namespace ccd_detail

/// @brief CCD of a point against a triangle.
/// @param p_t0, t0_t0, t1_t0, t2_t0  point and triangle corners at t = 0 (m)
/// @param p_t1, t0_t1, t1_t1, t2_t1  the same at t = 1 (m)
/// @param settings  valid settings (check_ccd_settings); not checked here
DIFFIPC_HD inline CCDResult point_triangle_ccd(const vec3& p_t0, const vec3& t0_t0, const vec3& t1_t0,
    const vec3& t2_t0, const vec3& p_t1, const vec3& t0_t1, const vec3& t1_t1, const vec3& t2_t1,
    const CCDSettings& settings)
{
    const vec3 x_t0[4] = { p_t0, t0_t0, t1_t0, t2_t0 }, x_t1[4] = { p_t1, t0_t1, t1_t1, t2_t1 };
    return ccd_detail::additive_ccd<4>(x_t0, x_t1, 1, ccd_detail::PointTriangleLowerBound(), settings);
}

/// @brief CCD of two segments (ea0, ea1) and (eb0, eb1).
/// @param ea0_t0, ea1_t0, eb0_t0, eb1_t0  edge endpoints at t = 0 (m)
/// @param ea0_t1, ea1_t1, eb0_t1, eb1_t1  the same at t = 1 (m)
DIFFIPC_HD inline CCDResult edge_edge_ccd(const vec3& ea0_t0, const vec3& ea1_t0, const vec3& eb0_t0,
    const vec3& eb1_t0, const vec3& ea0_t1, const vec3& ea1_t1, const vec3& eb0_t1, const vec3& eb1_t1,
    const CCDSettings& settings)
{
    const vec3 x_t0[4] = { ea0_t0, ea1_t0, eb0_t0, eb1_t0 }, x_t1[4] = { ea0_t1, ea1_t1, eb0_t1, eb1_t1 };
    return ccd_detail::additive_ccd<4>(x_t0, x_t1, 2, ccd_detail::EdgeEdgeLowerBound(), settings);
}

/// @brief CCD of a point against a segment (e0, e1), in 3D or in 2D (z = 0).
/// @param p_t0, e0_t0, e1_t0  point and segment endpoints at t = 0 (m)
/// @param p_t1, e0_t1, e1_t1  the same at t = 1 (m)
DIFFIPC_HD inline CCDResult point_edge_ccd(const vec3& p_t0, const vec3& e0_t0, const vec3& e1_t0, const vec3& p_t1,
    const vec3& e0_t1, const vec3& e1_t1, const CCDSettings& settings)
{
    const vec3 x_t0[3] = { p_t0, e0_t0, e1_t0 }, x_t1[3] = { p_t1, e0_t1, e1_t1 };
    return ccd_detail::additive_ccd<3>(x_t0, x_t1, 1, ccd_detail::PointEdgeLowerBound(), settings);
}

/// @brief CCD of two points.
/// @param p0_t0, p1_t0  the points at t = 0 (m)
/// @param p0_t1, p1_t1  the points at t = 1 (m)
DIFFIPC_HD inline CCDResult point_point_ccd(
    const vec3& p0_t0, const vec3& p1_t0, const vec3& p0_t1, const vec3& p1_t1, const CCDSettings& settings)
{
    const vec3 x_t0[2] = { p0_t0, p1_t0 }, x_t1[2] = { p0_t1, p1_t1 };
    return ccd_detail::additive_ccd<2>(x_t0, x_t1, 1, ccd_detail::PointPointLowerBound(), settings);
}

/// @brief CCD of a point against an infinite plane that translates with its origin and keeps its
/// normal. The distance is the unsigned |(p - o) . n| / |n|; it is linear in t on each side, so
/// the first time it reaches dmin is found in closed form (no iterations; conservative_rescaling
/// only sets the returned toi = s times that time, so that the gap at toi is (1 - s) times the
/// starting gap).
/// @param p_t0, p_t1                        the point at t = 0 and t = 1 (m)
/// @param plane_origin_t0, plane_origin_t1  a point of the plane at t = 0 and t = 1 (m)
/// @param normal                            finite and nonzero, any length (checked by the host caller)
DIFFIPC_HD inline CCDResult point_plane_ccd(const vec3& p_t0, const vec3& p_t1, const vec3& plane_origin_t0,
    const vec3& plane_origin_t1, const vec3& normal, const CCDSettings& settings)
{
    const double u = ccd_detail::unit_roundoff;
    CCDResult result;
    result.collision = true;
    result.toi = 0;
    result.iterations = 1;
    result.budget_exhausted = false;
    if (!all_finite(p_t0) || !all_finite(p_t1) || !all_finite(plane_origin_t0) || !all_finite(plane_origin_t1))
        return result;

    // Exactly, h(t) = (p(t) - o(t)).n / |n| = h0 + t v is linear and d(t) = |h(t)|.
    const double nn = norm(normal);
    const vec3 w = p_t0 - plane_origin_t0;
    const vec3 dp = p_t1 - p_t0, dorigin = plane_origin_t1 - plane_origin_t0;
    const vec3 dw = dp - dorigin;
    const double h0 = dot(w, normal) / nn, v = dot(dw, normal) / nn;
    // Rounding: of w (u |w| |n|), the dot product (3u |w||n|), the norm and the division
    // (4u |h0|): |h0 error| <= 8u |w|; of dw (u (|dp| + |do|) + u |dw|), then as for h0:
    // |v error| <= 8u (|dp| + |do| + |dw|).
    const double h_error = 8 * u * norm(w);
    const double v_error = 8 * u * (norm(dp) + norm(dorigin) + norm(dw));
    const double d0 = fabs(h0) - h_error;
    const double gap0 = d0 - settings.min_distance - 4 * u * (fabs(d0) + settings.min_distance);
    if (!(gap0 > 0))
        return result;
    // gap0 > 0 implies |h0| > h_error, so the side of the plane is known: d(t) >= d0 - t * approach
    // while on that side, and d first reaches dmin no earlier than gap0 / approach.
    const double approach = (max_of(0.0, h0 > 0 ? -v : v) + v_error) * (1 + 4 * u);
    if (settings.t_max * approach * (1 + 2 * u) < gap0) {
        result.collision = false;
        result.toi = settings.t_max;
        return result;
    }
    // gap(toi) >= gap0 - toi * approach >= (1 - s) gap0; toi < t_max since s < 1.
    result.toi = settings.conservative_rescaling * (gap0 / approach) * (1 - 4 * u);
    return result;
}

/// @brief One query of the batch layout (cuda/ccd/ccd.cuh's ccd_batch): the 2 n vertex positions
/// of a primitive pair of n vertices, xyz per vertex, the n positions at t = 0 in the kind's
/// vertex order, then the same n at t = 1.
/// @param kind      the primitive pair
/// @param query     2 * ccd_vertex_count(kind) * 3 doubles (m)
/// @param settings  valid settings (check_ccd_settings); not checked here
DIFFIPC_HD inline CCDResult ccd_query(CCDKind kind, const double* query, const CCDSettings& settings)
{
    vec3 x[8];
    for (int i = 0; i < 2 * ccd_vertex_count(kind); ++i)
        x[i] = vec3::load(query + 3 * i);
    switch (kind) {
    case CCDKind::POINT_TRIANGLE:
        return point_triangle_ccd(x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], settings);
    case CCDKind::EDGE_EDGE:
        return edge_edge_ccd(x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], settings);
    case CCDKind::POINT_EDGE:
        return point_edge_ccd(x[0], x[1], x[2], x[3], x[4], x[5], settings);
    case CCDKind::POINT_POINT:
        return point_point_ccd(x[0], x[1], x[2], x[3], settings);
    }
    return CCDResult(); // not a kind: collision at t = 0
}

} // namespace diffipc::kernels
