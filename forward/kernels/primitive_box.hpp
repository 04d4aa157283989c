#pragma once
/// @file primitive_box.hpp
/// Swept, inflated axis-aligned boxes of contact primitives and their overlap test, on host and device: the
/// CPU's broad phase (forward/contact/broad_phase/aabb.cpp) and the GPU's (cuda/broad_phase/) build their boxes
/// with this code, so the GPU broad phase finds exactly the CPU's pairs.
///
/// Inflation convention: every box grows by radius = inflation / 2 per side, then each bound is
/// rounded outward by at least one ulp (v -/+ (|v| 2^-52 + 2^-1074)). If two primitives come within distance
/// d <= inflation at some t of the linear motion x(t) = (1 - t) x_t0 + t x_t1, their boxes overlap. A box with a
/// non-finite coordinate has min[0] = NaN (it overlaps nothing; callers reject it).
///
/// Bitwise equality of the two paths needs the device code compiled without fused multiply-adds (|v| eps +
/// denorm_min would otherwise contract): the .cu files that include this are compiled with -fmad=false
/// (cuda/CMakeLists.txt).
///
/// Layouts: positions are #V by dim doubles, row-major (vertex v at x + v * dim), metres; a primitive's vertex
/// ids are N consecutive ints (an edge row, a face row, or one collision vertex). 2D boxes have min z = max z = 0.

#include "forward/kernels/host_device.hpp"

#include <cstddef>

namespace diffipc {
namespace kernels {

    /// A closed box; 2D boxes have min[2] = max[2] = 0.
    struct Box {
        double min[3];
        double max[3];
    };

    namespace box_detail {
        constexpr double box_epsilon = 0x1p-52; ///< std::numeric_limits<double>::epsilon()
        constexpr double box_denorm_min = 0x1p-1074; ///< std::numeric_limits<double>::denorm_min()
    } // namespace box_detail

    /// At least one ulp down: |v| 2^-52 >= ulp(v) for normal v, and the smallest subnormal covers v = 0.
    DIFFIPC_HD inline double box_round_down(double v)
    {
        return v - (fabs(v) * box_detail::box_epsilon + box_detail::box_denorm_min);
    }
    DIFFIPC_HD inline double box_round_up(double v)
    {
        return v + (fabs(v) * box_detail::box_epsilon + box_detail::box_denorm_min);
    }

    /// @brief Do the closed boxes share a point? (False if either has a NaN bound.)
    DIFFIPC_HD inline bool boxes_overlap(const Box& a, const Box& b)
    {
        return a.min[0] <= b.max[0] && b.min[0] <= a.max[0] //
            && a.min[1] <= b.max[1] && b.min[1] <= a.max[1] //
            && a.min[2] <= b.max[2] && b.min[2] <= a.max[2];
    }

    /// True unless the box was marked non-finite (min[0] NaN).
    DIFFIPC_HD inline bool box_is_finite(const Box& b)
    {
        bool finite = true;
        for (int k = 0; k < 3; ++k)
            finite = finite && is_finite(b.min[k]) && is_finite(b.max[k]);
        return finite;
    }

    /// @brief The box of the N vertices `ids` at both ends of the step, grown by `radius` per side and rounded
    /// outward by at least one ulp.
    /// @param x_t0, x_t1  #V by DIM positions at t = 0 and t = 1 (m), row-major
    /// @param ids         N vertex indices
    /// @param radius      inflation / 2 (m)
    template <int N, int DIM>
    DIFFIPC_HD inline Box primitive_box(const double* x_t0, const double* x_t1, const int* ids, double radius)
    {
        double lo[3] = { 0, 0, 0 }, hi[3] = { 0, 0, 0 };
        bool finite = true;
        for (int k = 0; k < DIM; ++k) {
            lo[k] = infinity<double>();
            hi[k] = -lo[k];
        }
        for (int a = 0; a < N; ++a) {
            const double* p0 = x_t0 + std::size_t(ids[a]) * DIM;
            const double* p1 = x_t1 + std::size_t(ids[a]) * DIM;
            for (int k = 0; k < DIM; ++k) {
                finite = finite && is_finite(p0[k]) && is_finite(p1[k]);
                // std::min / std::max: the first argument unless the second compares smaller (larger).
                lo[k] = min_of(lo[k], min_of(p0[k], p1[k]));
                hi[k] = max_of(hi[k], max_of(p0[k], p1[k]));
            }
        }
        Box box;
        for (int k = 0; k < DIM; ++k) {
            box.min[k] = box_round_down(lo[k] - radius);
            box.max[k] = box_round_up(hi[k] + radius);
        }
        for (int k = DIM; k < 3; ++k)
            box.min[k] = box.max[k] = 0;
        if (!finite)
            box.min[0] = NAN; // min/max skip NaN: mark the box so that callers can reject it
        return box;
    }

} // namespace kernels
} // namespace diffipc
