#pragma once
/// @file ccd.cuh
/// Conservative continuous collision detection on the GPU: the port of the CPU
/// CCD (forward/contact/ccd/ccd.{hpp,cpp}) to __host__ __device__ code on plain
/// doubles, and a batched API that runs many queries in one kernel.
///
/// Contract: the CPU CCD's, word for word (see forward/contact/ccd/ccd.hpp).
/// With d(t) the exact distance between the primitives at time t (vertices
/// moving linearly from t = 0 to t = 1) and dmin = settings.min_distance:
///  - collision == false: d(t) > dmin for all t in [0, t_max]; never a false
///    negative, touching and degenerate configurations included (rounding is
///    accounted for);
///  - collision == true: toi in [0, t_max) is certified free, d > dmin on
///    [0, toi], with a gap at toi of at least (1 - s) times the certified
///    starting gap; toi == 0 means an invalid start (at or within round-off of
///    dmin); it may be a false positive (plain ACCD, round-off, budget);
///  - budget_exhausted == true: collision is true and toi the time certified so far;
///  - non-finite coordinates give collision == true, toi = 0.
/// Algorithm: Additive CCD (Li, Kaufman, Jiang 2021, Alg. 1) with certified
/// distance lower bounds (distance_lower_bound.cuh) and bounds of the
/// trajectory's rounding; the proof is in the comments of the CPU ccd.cpp.
///
/// Same results as the CPU, bit for bit: every function here performs the CPU
/// code's floating-point operations in the same order (Eigen's 3-vector sums
/// as ((a + b) + c), its cross product, std::min/std::max/std::max_element
/// tie and NaN rules, division where the CPU divides), and IEEE 754 double
/// +, -, *, / and sqrt are correctly rounded on both sides (nvcc's defaults
/// -prec-div=true, -prec-sqrt=true, no -use_fast_math; double subnormals are
/// never flushed on the GPU). What a compiler would change is the contraction
/// of a * b + c into a fused multiply-add, which nvcc does by default on the
/// device: cuda/ccd/ccd.cu is compiled with -fmad=false (explicit __dmul_rn /
/// __dadd_rn are not used), and the CPU side as this repo builds it (g++ -O2
/// on x86-64 without -march, so no FMA instructions) never contracts. So
/// collision, toi, iterations and budget_exhausted are the CPU's, bit for bit,
/// for coordinates in the proof's range (magnitudes between about 1e-60 and
/// 1e60); tests/cuda/ccd/test_ccd.cpp checks this on the sample queries under
/// several settings, on the host and on the GPU. It matters: with contraction
/// allowed (g++ -mfma -ffp-contract=fast on the host code) the toi and
/// iterations of 1 to 6% of the sample queries differ (their collision flags
/// did not).
/// A .cu file of another target that calls these functions gets the CPU's bits
/// only if it is compiled with -fmad=false too; with FMA the results are still
/// conservative (fused operations only shrink the rounding errors the bounds
/// allow for), but no longer bitwise equal.
///
/// Names are in diffipc::gpu rather than diffipc::cuda so that libcu++'s
/// ::cuda namespace is not shadowed inside diffipc.
///
/// Positions are in metres; 2D callers set z = 0.

#include "cuda/ccd/distance_lower_bound.cuh"
#include "cuda/common/kernels.cuh"

#include <cstddef>
#include <vector>

namespace diffipc {
namespace gpu {

    /// The CPU's CCDSettings (forward/contact/ccd/ccd.hpp), field for field.
    struct CCDSettings {
        /// dmin (m): report a collision when the distance may reach this value (>= 0).
        double min_distance = 0;
        /// s in (0, 1): step fraction of the certified free time; the gap left at toi is (1 - s) of the start.
        double conservative_rescaling = 0.9;
        /// Budget of distance evaluations per query (the initial one included).
        int max_iterations = 10000000;
        /// Only [0, t_max] of the trajectory is checked (t_max >= 0).
        double t_max = 1;
        /// Go on past the first gap below (1 - s) times the start, down to refine_tolerance lp t_max.
        bool refine = false;
        /// Relative gap below which a refined search reports a collision (> 0).
        double refine_tolerance = 1e-6;
    };

    /// The CPU's CCDResult, field for field.
    struct CCDResult {
        /// True when an impact (distance <= dmin) could not be excluded on [0, t_max].
        bool collision = true;
        /// Certified free time when collision is true; t_max otherwise.
        double toi = 0;
        /// Distance evaluations used.
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

    namespace detail {

        /// The certified gap at time t: lower bound of the distance at the computed positions, less the
        /// trajectory's rounding tau and dmin, less the rounding of these subtractions.
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

        /// Additive CCD on N vertices, the first n_first of which form one primitive and the rest the other.
        /// The CPU's additive_ccd step for step (its comments give the proof). Settings are not checked here
        /// (no exceptions on the device): ccd_batch checks them on the host; invalid values never give
        /// "no collision" for an impact but are not errors here.
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
            // Displacements less their mean (a common translation leaves distances unchanged).
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
            // Lipschitz constant of the distance in t: the largest relative speed of a vertex pair.
            double relative_speed = 0;
            for (int i = 0; i < n_first; ++i)
                for (int j = n_first; j < N; ++j)
                    relative_speed = max_of(relative_speed, norm(v[i] - v[j]));
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
                // The evaluated and the Lipschitz-propagated lower bounds of the gap at t_next.
                const double propagated = gap - lp * (t_next - t) * (1 + 4 * u) - 2 * u * gap;
                const double evaluated = certified_gap<N>(x_t0, v, t_next, lower_bound, tau, dmin);
                const double gap_next = evaluated > propagated ? evaluated : propagated;
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
            DIFFIPC_HD double operator()(const vec3 (&x)[2]) const
            {
                return point_point_distance_lower_bound(x[0], x[1]);
            }
        };

    } // namespace detail

    /// @brief CCD of a point against a triangle.
    /// @param p_t0, t0_t0, t1_t0, t2_t0  point and triangle corners at t = 0 (m)
    /// @param p_t1, t0_t1, t1_t1, t2_t1  the same at t = 1 (m)
    /// @param settings  valid settings (check_ccd_settings); not checked here
    DIFFIPC_HD inline CCDResult point_triangle_ccd(const vec3& p_t0, const vec3& t0_t0, const vec3& t1_t0,
        const vec3& t2_t0, const vec3& p_t1, const vec3& t0_t1, const vec3& t1_t1, const vec3& t2_t1,
        const CCDSettings& settings)
    {
        const vec3 x_t0[4] = { p_t0, t0_t0, t1_t0, t2_t0 }, x_t1[4] = { p_t1, t0_t1, t1_t1, t2_t1 };
        return detail::additive_ccd<4>(x_t0, x_t1, 1, detail::PointTriangleLowerBound(), settings);
    }

    /// @brief CCD of two segments (ea0, ea1) and (eb0, eb1).
    /// @param ea0_t0, ea1_t0, eb0_t0, eb1_t0  edge endpoints at t = 0 (m)
    /// @param ea0_t1, ea1_t1, eb0_t1, eb1_t1  the same at t = 1 (m)
    DIFFIPC_HD inline CCDResult edge_edge_ccd(const vec3& ea0_t0, const vec3& ea1_t0, const vec3& eb0_t0,
        const vec3& eb1_t0, const vec3& ea0_t1, const vec3& ea1_t1, const vec3& eb0_t1, const vec3& eb1_t1,
        const CCDSettings& settings)
    {
        const vec3 x_t0[4] = { ea0_t0, ea1_t0, eb0_t0, eb1_t0 }, x_t1[4] = { ea0_t1, ea1_t1, eb0_t1, eb1_t1 };
        return detail::additive_ccd<4>(x_t0, x_t1, 2, detail::EdgeEdgeLowerBound(), settings);
    }

    /// @brief CCD of a point against a segment (e0, e1), in 3D or in 2D (z = 0).
    /// @param p_t0, e0_t0, e1_t0  point and segment endpoints at t = 0 (m)
    /// @param p_t1, e0_t1, e1_t1  the same at t = 1 (m)
    DIFFIPC_HD inline CCDResult point_edge_ccd(const vec3& p_t0, const vec3& e0_t0, const vec3& e1_t0, const vec3& p_t1,
        const vec3& e0_t1, const vec3& e1_t1, const CCDSettings& settings)
    {
        const vec3 x_t0[3] = { p_t0, e0_t0, e1_t0 }, x_t1[3] = { p_t1, e0_t1, e1_t1 };
        return detail::additive_ccd<3>(x_t0, x_t1, 1, detail::PointEdgeLowerBound(), settings);
    }

    /// @brief CCD of two points.
    /// @param p0_t0, p1_t0  the points at t = 0 (m)
    /// @param p0_t1, p1_t1  the points at t = 1 (m)
    DIFFIPC_HD inline CCDResult point_point_ccd(
        const vec3& p0_t0, const vec3& p1_t0, const vec3& p0_t1, const vec3& p1_t1, const CCDSettings& settings)
    {
        const vec3 x_t0[2] = { p0_t0, p1_t0 }, x_t1[2] = { p0_t1, p1_t1 };
        return detail::additive_ccd<2>(x_t0, x_t1, 1, detail::PointPointLowerBound(), settings);
    }

    /// @brief One query of the batch layout (see ccd_batch): the 2 n vertex positions of a primitive pair of n
    /// vertices, xyz per vertex, the n positions at t = 0 in the kind's vertex order, then the same n at t = 1.
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

    // ---------------------------------------------------------------------------------------------------------
    // Host side (cuda/ccd/ccd.cu).

    /// @brief The CPU CCD's settings check, with its messages.
    /// @throws InputError (forward/common/error.hpp) on min_distance < 0, conservative_rescaling outside (0, 1),
    /// t_max < 0, max_iterations < 1, refine_tolerance <= 0 or non-finite values
    void check_ccd_settings(const CCDSettings& settings);

    /// Device timing of one batch, from CUDA events (milliseconds).
    struct CCDBatchTiming {
        float kernel_ms = 0; ///< the kernel alone
        float total_ms = 0; ///< copy in, kernel, copy out (allocation excluded)
    };

    /// @brief Run many CCD queries of one kind on the GPU, one thread per query: copy the queries to the device,
    /// launch, copy the results back.
    /// @param kind       the primitive pair of every query
    /// @param vertices   n_queries * 2 * ccd_vertex_count(kind) * 3 doubles: query q starts at
    ///                   vertices + q * 6 * ccd_vertex_count(kind) and holds its vertices at t = 0 in the kind's
    ///                   order, then the same vertices at t = 1, xyz each (m). For point-triangle and edge-edge
    ///                   that is 8 positions (24 doubles) per query, the row order of the CCD sample queries; for
    ///                   point-edge 6, for point-point 4.
    /// @param n_queries  number of queries (0 is fine: no device call)
    /// @param settings   checked first (check_ccd_settings)
    /// @param timing     if non-null, the device times of this batch
    /// @return           one result per query, in order; bitwise the CPU CCD's (see the file comment)
    /// @throws InputError on invalid settings; std::runtime_error starting "no CUDA device: " when there is no
    ///         usable GPU, or naming the failed CUDA call
    std::vector<CCDResult> ccd_batch(CCDKind kind, const double* vertices, std::size_t n_queries,
        const CCDSettings& settings, CCDBatchTiming* timing = nullptr);

} // namespace gpu
} // namespace diffipc
