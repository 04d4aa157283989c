#pragma once
// Helpers for the tests of the shared kernels (forward/kernels/) and of the GPU code that calls them:
// point quadruples, random and degenerate, and comparisons of the kernels' row-major arrays with
// Eigen results.

#include "forward/kernels/vec3.hpp"

#include <Eigen/Core>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

namespace diffipc::test {

using Quad = std::array<Eigen::Vector3d, 4>;

inline kernels::vec3 to_gpu(const Eigen::Vector3d& v) { return kernels::vec3(v.x(), v.y(), v.z()); }

/// Hand-made degenerate configurations, read as (p, e0, e1, -), (p, t0, t1, t2) or
/// (ea0, ea1, eb0, eb1): points on an edge's line and on its ends, degenerate edges, points in a
/// triangle's plane, collinear and sliver triangles, parallel, collinear, crossing, nearly
/// parallel and touching edges, coincident points.
inline std::vector<Quad> degenerate_quads()
{
    using V = Eigen::Vector3d;
    const V o(0, 0, 0), x(1, 0, 0), y(0, 1, 0);
    std::vector<Quad> q = {
        { V(2, 0, 0), o, x, y }, // p on the line beyond e1
        { V(-1, 0, 0), o, x, y }, // before e0
        { V(0.5, 0, 0), o, x, y }, // on the edge
        { o, o, x, y }, // p = e0
        { V(0.3, 0.2, 0.1), V(1, 1, 1), V(1, 1, 1), y }, // degenerate edge e0 = e1
        { V(0, 1, 0), o, x, V(2, 3, 4) }, // t = 0 exactly
        { V(1, 1, 0), o, x, V(2, 3, 4) }, // t = 1 exactly
        { V(0.2, 0.2, 1), o, x, y }, // above the triangle
        { V(0.2, 0.2, 0), o, x, y }, // in the triangle
        { V(0.5, -1, 0.3), o, x, y }, // over an edge's region
        { V(-1, -1, 0.5), o, x, y }, // over a corner's region
        { V(0.3, 0.5, 0.2), o, x, V(2, 0, 0) }, // collinear triangle
        { V(0.3, 0.5, 0.2), o, o, y }, // t0 = t1
        { V(0.3, 0.5, 0.2), o, x, V(0.5, 1e-12, 0) }, // sliver
        { V(0.3, 0.4, 0.2), o, x, V(0.5, 1e-9, 0) }, // thin triangle
        { V(0.5, 0, 0), o, x, y }, // on an edge of the triangle, in its plane
        { o, x, y, V(1, 1, 0) }, // parallel edges
        { o, x, V(0.5, 1, 0.3), V(1.5, 1, 0.3) }, // parallel, shifted
        { o, x, V(0.5, 0, 0), V(2, 0, 0) }, // collinear, overlapping
        { o, x, V(0.5, -0.5, 0), V(0.5, 0.5, 0) }, // crossing
        { o, x, V(0.5, -0.5, 0.1), V(0.5, 0.5, 0.1) }, // skew, closest points inside both
        { o, x, V(0.2, 0.1, 0.05), V(0.8, 0.1, 0.05 + 1e-7) }, // nearly parallel
        { o, x, V(0.2, 1e-3, 1e-4), V(0.9, 1e-3 + 1e-9, 1e-4) }, // nearly parallel and close
        { o, o, V(0.5, 1, 0.3), V(1.5, 1, 0.3) }, // degenerate edge a
        { o, x, x, V(1, 1, 1) }, // shared endpoint
        { o, x, x, V(2, 0, 0) }, // collinear, touching
        { o, x, V(1, 1, 0), V(0, 1, 0) }, // anti-parallel
        { o, o, o, o }, // all coincident
        { V(1e-3, 2e-3, 0.1), V(0.1, 0.1, 0.1), V(0.1, 0.1 + 1e-8, 0.1), V(0.3, 0.1, 0.1) }, // tiny edge
    };
    // The same, moved and scaled, and slightly perturbed (near-degenerate).
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-1, 1);
    const size_t base = q.size();
    for (size_t k = 0; k < base; ++k) {
        Quad moved = q[k], noisy = q[k];
        const V shift(u(rng), u(rng), u(rng));
        for (int a = 0; a < 4; ++a) {
            moved[size_t(a)] = 0.37 * q[k][size_t(a)] + shift;
            noisy[size_t(a)] = q[k][size_t(a)] + 1e-10 * V(u(rng), u(rng), u(rng));
        }
        q.push_back(moved);
        q.push_back(noisy);
    }
    return q;
}

/// `count` quadruples of points uniform in [-1, 1]^3.
inline std::vector<Quad> random_quads(int count, unsigned seed)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1, 1);
    std::vector<Quad> q(static_cast<size_t>(count));
    for (Quad& a : q)
        for (Eigen::Vector3d& p : a)
            p = Eigen::Vector3d(u(rng), u(rng), u(rng));
    return q;
}

/// Random and degenerate quadruples.
inline std::vector<Quad> test_quads(unsigned seed = 1)
{
    std::vector<Quad> q = random_quads(300, seed);
    const std::vector<Quad> d = degenerate_quads();
    q.insert(q.end(), d.begin(), d.end());
    return q;
}

/// Tally of a comparison: the largest entrywise difference (NaN matches NaN), the largest |cpu|
/// entry, and the entries whose bits differ.
struct Tally {
    double difference = 0, scale = 0;
    long entries = 0, bitwise_differences = 0;
    bool nan_mismatch = false;

    /// Adds the comparison of gpu[r * cols + c] (row-major) with cpu(r, c).
    template <typename Derived> void add(const double* gpu, const Eigen::MatrixBase<Derived>& cpu)
    {
        const Eigen::Index rows = cpu.rows(), cols = cpu.cols();
        double local_difference = 0, local_scale = 0;
        for (Eigen::Index r = 0; r < rows; ++r)
            for (Eigen::Index c = 0; c < cols; ++c) {
                const double a = gpu[r * cols + c], b = cpu(r, c);
                ++entries;
                if (std::memcmp(&a, &b, sizeof(double)) != 0 && !(a == b))
                    ++bitwise_differences;
                if (std::isnan(a) || std::isnan(b)) {
                    nan_mismatch = nan_mismatch || std::isnan(a) != std::isnan(b);
                    continue;
                }
                local_scale = std::max(local_scale, std::abs(b));
                local_difference = std::max(local_difference, std::abs(a - b));
            }
        // Relative to this array's own scale, so that a small array is not hidden by a large one.
        if (local_scale > 0)
            difference = std::max(difference, local_difference / local_scale);
        else
            difference = std::max(difference, local_difference);
        scale = std::max(scale, local_scale);
    }
    void add(double gpu, double cpu)
    {
        Eigen::Matrix<double, 1, 1> m;
        m(0, 0) = cpu;
        add(&gpu, m);
    }

    /// Expects agreement to `relative` (relative to each array's largest entry).
    void expect(double relative, const std::string& what) const
    {
        EXPECT_FALSE(nan_mismatch) << what << ": NaN on one side only";
        EXPECT_LE(difference, relative) << what;
        std::printf("  %-40s %6ld entries, %4ld differ in their bits, largest relative difference %.2e\n", what.c_str(),
            entries, bitwise_differences, difference);
    }
};

} // namespace diffipc::test
