#include "forward/contact/ccd/ccd.hpp"

#include "forward/common/error.hpp"
#include "forward/contact/ccd/distance_lower_bound.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

namespace diffipc {

namespace {

    constexpr double u = std::numeric_limits<double>::epsilon() / 2; // unit round-off

    void check_settings(const CCDSettings& s)
    {
        if (!(s.min_distance >= 0) || !std::isfinite(s.min_distance))
            throw InputError("ccd.min_distance", "must be finite and >= 0, got " + format_number(s.min_distance));
        if (!(s.conservative_rescaling > 0 && s.conservative_rescaling < 1))
            throw InputError("ccd.conservative_rescaling",
                "must be in (0, 1) (0.9 is usual), got " + format_number(s.conservative_rescaling));
        if (!(s.t_max >= 0) || !std::isfinite(s.t_max))
            throw InputError("ccd.t_max", "must be finite and >= 0, got " + format_number(s.t_max));
        if (!(s.refine_tolerance > 0) || !std::isfinite(s.refine_tolerance))
            throw InputError(
                "ccd.refine_tolerance", "must be finite and > 0, got " + format_number(s.refine_tolerance));
        if (s.max_iterations < 1)
            throw InputError("ccd.max_iterations", "must be >= 1, got " + std::to_string(s.max_iterations));
    }

    /// Additive CCD (Li, Kaufman, Jiang 2021, Alg. 1) on N vertices, the first
    /// n_first of which form one primitive and the rest the other.
    /// lower_bound(x) returns a certified lower bound of the distance between the
    /// primitives with vertex positions x (distance_lower_bound.hpp).
    ///
    /// Why it is conservative in floating point:
    ///  1. The exact trajectory X_i(t) = x_i,t0 + t (x_i,t1 - x_i,t0), shifted by
    ///     -t m for the mean displacement m (a common translation, so distances
    ///     are unchanged), is evaluated as fl(x_i,t0 + fl(t v_i)) with
    ///     v_i = fl(fl(x_i,t1 - x_i,t0) - m). Per component the computed position
    ///     is within u (t_max (|dx_i| + 2 |v_i|) + |x_i|) of the exact one; a
    ///     distance moves by at most the largest displacement of each primitive's
    ///     vertices, so gap(t) = lower_bound(computed x) - tau - dmin with
    ///     tau = 2 sqrt(3) u max_i(...) (we use 8 u) bounds the exact gap from below.
    ///  2. The exact distance is Lipschitz in t with constant
    ///     lp = max_{i in A, j in B} |v_i - v_j|, enlarged for the rounding of v:
    ///     d(t) = min over barycentric weights (a, b) of |sum a_i x_i(t) - sum b_j x_j(t)|,
    ///     each of these functions has slope at most |sum a_i v_i - sum b_j v_j|,
    ///     a convex function of (a, b) whose maximum is at a vertex pair, and a
    ///     minimum of lp-Lipschitz functions is lp-Lipschitz. This is never larger
    ///     than ACCD's max_A |v_i| + max_B |v_j| (with the mean removed) and
    ///     smaller for rotating primitives. So a certified gap g at t certifies
    ///     [t, t + g / lp], and g - lp (t' - t) bounds the gap at t'.
    ///  3. Each step goes s g / lp, s < 1; the slack (1 - s) g / lp absorbs the
    ///     rounding of t + dt as long as dt >= min_step = 16 u t_max / (1 - s).
    ///     A smaller step means the gap is within ~1e-14 (relative to the motion)
    ///     of zero, i.e. a touching contact up to round-off: we stop and report a
    ///     collision at the current certified time instead of stalling (this is
    ///     the safeguard for exactly touching configurations: a true distance of
    ///     zero can never be stepped over, its lower bound is <= 0 there and the
    ///     step sizes shrink to zero before it).
    ///  4. Every comparison is written so that NaN leads to "collision".
    template <int N, typename LowerBound>
    CCDResult additive_ccd(const std::array<Eigen::Vector3d, N>& x_t0, const std::array<Eigen::Vector3d, N>& x_t1,
        int n_first, const LowerBound& lower_bound, const CCDSettings& settings)
    {
        check_settings(settings);
        CCDResult result;
        result.collision = true;
        result.toi = 0;
        result.iterations = 0;
        result.budget_exhausted = false;
        for (int i = 0; i < N; ++i)
            if (!x_t0[i].allFinite() || !x_t1[i].allFinite())
                return result;

        const double t_max = settings.t_max, dmin = settings.min_distance, s = settings.conservative_rescaling;
        std::array<Eigen::Vector3d, N> v;
        Eigen::Vector3d mean = Eigen::Vector3d::Zero();
        for (int i = 0; i < N; ++i) {
            v[i] = x_t1[i] - x_t0[i];
            mean += v[i];
        }
        mean /= double(N);
        double position_scale = 0, velocity_scale = 0;
        for (int i = 0; i < N; ++i) {
            const double dx = v[i].cwiseAbs().maxCoeff();
            v[i] -= mean;
            const double vi = v[i].cwiseAbs().maxCoeff();
            const double xi = std::max(x_t0[i].cwiseAbs().maxCoeff(), (x_t0[i] + t_max * v[i]).cwiseAbs().maxCoeff());
            position_scale = std::max(position_scale, t_max * (dx + 2 * vi) + xi);
            velocity_scale = std::max(velocity_scale, dx + vi);
        }
        double relative_speed = 0;
        for (int i = 0; i < n_first; ++i)
            for (int j = n_first; j < N; ++j)
                relative_speed = std::max(relative_speed, (v[i] - v[j]).norm());
        // |v_exact - v_computed| <= sqrt(3) u (|dx| + |v|) per vertex, twice for a
        // difference; the difference and its norm round by 4u relative.
        const double lp = (relative_speed + 8 * u * velocity_scale) * (1 + 8 * u);
        const double tau = 8 * u * position_scale;

        std::array<Eigen::Vector3d, N> x;
        auto gap_at = [&](double t) {
            for (int i = 0; i < N; ++i)
                x[i] = x_t0[i] + t * v[i];
            const double d = lower_bound(x);
            return d - tau - dmin - 4 * u * (d + tau + dmin); // the last term covers the subtractions' rounding
        };

        result.iterations = 1;
        const double gap0 = gap_at(0);
        if (!(gap0 > 0))
            return result; // starts at or below dmin (up to round-off)
        if (!(lp > 0)) { // rigid translation: the distance is constant
            result.collision = false;
            result.toi = t_max;
            return result;
        }
        const double gap_stop = (1 - s) * gap0;
        // A refined search only decides "collision" below this gap; toi stays
        // the first time the gap fell below gap_stop.
        const double gap_collision
            = settings.refine ? std::min(gap_stop, settings.refine_tolerance * lp * t_max) : gap_stop;
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
            // Two certified lower bounds of the gap at t_next: the evaluated one and
            // the Lipschitz one; the latter guarantees (1 - s) gap after a step.
            const double propagated = gap - lp * (t_next - t) * (1 + 4 * u) - 2 * u * gap;
            const double evaluated = gap_at(t_next);
            const double gap_next = evaluated > propagated ? evaluated : propagated;
            // The first step is always taken (Alg. 1's "t > 0"): its gap is at least
            // (1 - s) gap0 by the Lipschitz bound, so toi = 0 only for invalid starts.
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

} // namespace

CCDResult point_triangle_ccd(const Eigen::Vector3d& p_t0, const Eigen::Vector3d& t0_t0, const Eigen::Vector3d& t1_t0,
    const Eigen::Vector3d& t2_t0, const Eigen::Vector3d& p_t1, const Eigen::Vector3d& t0_t1,
    const Eigen::Vector3d& t1_t1, const Eigen::Vector3d& t2_t1, const CCDSettings& settings)
{
    using X = std::array<Eigen::Vector3d, 4>;
    return additive_ccd<4>(
        X { p_t0, t0_t0, t1_t0, t2_t0 }, X { p_t1, t0_t1, t1_t1, t2_t1 }, 1,
        [](const X& x) { return point_triangle_distance_lower_bound(x[0], x[1], x[2], x[3]); }, settings);
}

CCDResult edge_edge_ccd(const Eigen::Vector3d& ea0_t0, const Eigen::Vector3d& ea1_t0, const Eigen::Vector3d& eb0_t0,
    const Eigen::Vector3d& eb1_t0, const Eigen::Vector3d& ea0_t1, const Eigen::Vector3d& ea1_t1,
    const Eigen::Vector3d& eb0_t1, const Eigen::Vector3d& eb1_t1, const CCDSettings& settings)
{
    using X = std::array<Eigen::Vector3d, 4>;
    return additive_ccd<4>(
        X { ea0_t0, ea1_t0, eb0_t0, eb1_t0 }, X { ea0_t1, ea1_t1, eb0_t1, eb1_t1 }, 2,
        [](const X& x) { return edge_edge_distance_lower_bound(x[0], x[1], x[2], x[3]); }, settings);
}

CCDResult point_edge_ccd(const Eigen::Vector3d& p_t0, const Eigen::Vector3d& e0_t0, const Eigen::Vector3d& e1_t0,
    const Eigen::Vector3d& p_t1, const Eigen::Vector3d& e0_t1, const Eigen::Vector3d& e1_t1,
    const CCDSettings& settings)
{
    using X = std::array<Eigen::Vector3d, 3>;
    return additive_ccd<3>(
        X { p_t0, e0_t0, e1_t0 }, X { p_t1, e0_t1, e1_t1 }, 1,
        [](const X& x) { return point_edge_distance_lower_bound(x[0], x[1], x[2]); }, settings);
}

CCDResult point_point_ccd(const Eigen::Vector3d& p0_t0, const Eigen::Vector3d& p1_t0, const Eigen::Vector3d& p0_t1,
    const Eigen::Vector3d& p1_t1, const CCDSettings& settings)
{
    using X = std::array<Eigen::Vector3d, 2>;
    return additive_ccd<2>(
        X { p0_t0, p1_t0 }, X { p0_t1, p1_t1 }, 1,
        [](const X& x) { return point_point_distance_lower_bound(x[0], x[1]); }, settings);
}

CCDResult point_plane_ccd(const Eigen::Vector3d& p_t0, const Eigen::Vector3d& p_t1,
    const Eigen::Vector3d& plane_origin_t0, const Eigen::Vector3d& plane_origin_t1, const Eigen::Vector3d& normal,
    const CCDSettings& settings)
{
    check_settings(settings);
    if (!normal.allFinite() || !(normal.squaredNorm() > 0))
        throw InputError("normal", "the plane normal must be finite and nonzero");
    CCDResult result;
    result.collision = true;
    result.toi = 0;
    result.iterations = 1;
    result.budget_exhausted = false;
    if (!p_t0.allFinite() || !p_t1.allFinite() || !plane_origin_t0.allFinite() || !plane_origin_t1.allFinite())
        return result;

    // Exactly, h(t) = (p(t) - o(t)).n / |n| = h0 + t v is linear and d(t) = |h(t)|.
    const double nn = normal.norm();
    const Eigen::Vector3d w = p_t0 - plane_origin_t0;
    const Eigen::Vector3d dp = p_t1 - p_t0, dorigin = plane_origin_t1 - plane_origin_t0;
    const Eigen::Vector3d dw = dp - dorigin;
    const double h0 = w.dot(normal) / nn, v = dw.dot(normal) / nn;
    // Rounding: of w (u |w| |n|), the dot product (3u |w||n|), the norm and the
    // division (4u |h0|): |h0 error| <= 8u |w|; of dw (u (|dp| + |do|) + u |dw|),
    // then as for h0: |v error| <= 8u (|dp| + |do| + |dw|).
    const double h_error = 8 * u * w.norm();
    const double v_error = 8 * u * (dp.norm() + dorigin.norm() + dw.norm());
    const double d0 = std::abs(h0) - h_error;
    const double gap0 = d0 - settings.min_distance - 4 * u * (std::abs(d0) + settings.min_distance);
    if (!(gap0 > 0))
        return result;
    // gap0 > 0 implies |h0| > h_error, so the side of the plane is known:
    // d(t) >= d0 - t * approach while on that side, and d first reaches dmin no
    // earlier than gap0 / approach.
    const double approach = (std::max(0.0, h0 > 0 ? -v : v) + v_error) * (1 + 4 * u);
    if (settings.t_max * approach * (1 + 2 * u) < gap0) {
        result.collision = false;
        result.toi = settings.t_max;
        return result;
    }
    // gap(toi) >= gap0 - toi * approach >= (1 - s) gap0; toi < t_max since s < 1.
    result.toi = settings.conservative_rescaling * (gap0 / approach) * (1 - 4 * u);
    return result;
}

} // namespace diffipc
