#pragma once
/// @file line_line.hpp
/// The squared distance between two
/// infinite lines, with gradient and Hessian. Derivatives are vertex-major in argument order
/// (ea0, ea1, eb0, eb1), xyz per vertex; Hessians row-major.

#include "forward/kernels/distance/distance_kernels.hpp"

namespace diffipc::kernels {

namespace line_line_detail {
    // Line-line is the point-plane kernel with r = ea0 - eb0, a = ea1 - ea0, b = eb1 - eb0,
    // rewritten for the pull-back in variables sharing ea0: y1 = ea1 - ea0, y2 = eb0 - ea0,
    // y3 = eb1 - ea0, i.e. (r, a, b) = (-y2, y1, y3 - y2).

    /// (g_r, g_a, g_b) -> (g_a, -g_r - g_b, g_b)
    template <class T> DIFFIPC_HD inline void to_shared_vertex_gradient(const T* g, T* gy)
    {
        for (int i = 0; i < 3; ++i) {
            gy[i] = g[3 + i];
            gy[3 + i] = -g[i] - g[6 + i];
            gy[6 + i] = g[6 + i];
        }
    }

    /// Entry (i, j) of the 3x3 block (I, J) of a 9 x 9 row-major matrix.
    template <class T> DIFFIPC_HD inline T block_entry(const T* H, int I, int J, int i, int j)
    {
        return H[(3 * I + i) * 9 + 3 * J + j];
    }

    /// The same change of variables for 9 x 9 row-major Hessians (blocks B(i, j), i, j in r, a, b).
    template <class T> DIFFIPC_HD inline void to_shared_vertex_hessian(const T* H, T* Hy)
    {
        constexpr int r = 0, a = 1, b = 2;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) {
                const T y00 = block_entry(H, a, a, i, j);
                const T y01 = -block_entry(H, a, r, i, j) - block_entry(H, a, b, i, j);
                const T y02 = block_entry(H, a, b, i, j);
                const T y11 = block_entry(H, r, r, i, j) + block_entry(H, r, b, i, j) + block_entry(H, b, r, i, j)
                    + block_entry(H, b, b, i, j);
                const T y12 = -block_entry(H, r, b, i, j) - block_entry(H, b, b, i, j);
                const T y22 = block_entry(H, b, b, i, j);
                Hy[(0 + i) * 9 + 0 + j] = y00;
                Hy[(0 + i) * 9 + 3 + j] = y01;
                Hy[(0 + i) * 9 + 6 + j] = y02;
                Hy[(3 + i) * 9 + 3 + j] = y11;
                Hy[(3 + i) * 9 + 6 + j] = y12;
                Hy[(6 + i) * 9 + 6 + j] = y22;
                // lower blocks are the transposes of the upper ones
                Hy[(3 + j) * 9 + 0 + i] = y01;
                Hy[(6 + j) * 9 + 0 + i] = y02;
                Hy[(6 + j) * 9 + 3 + i] = y12;
            }
    }
} // namespace line_line_detail

/// @brief Squared distance between the lines through ea0, ea1 and eb0, eb1,
/// \f$ ((e_{a0} - e_{b0}) \cdot n)^2 / |n|^2 \f$, \f$ n = (e_{a1} - e_{a0}) \times (e_{b1} - e_{b0}) \f$
/// (m^2); undefined for parallel lines.
template <class T>
DIFFIPC_HD inline T line_line_distance(const Vec3<T>& ea0, const Vec3<T>& ea1, const Vec3<T>& eb0, const Vec3<T>& eb1)
{
    return distance_kernels::point_plane(ea0 - eb0, ea1 - ea0, eb1 - eb0, nullptr, nullptr);
}

/// @brief Gradient of line_line_distance. @param g out: 12 (d/dea0, d/dea1, d/deb0, d/deb1), m
template <class T>
DIFFIPC_HD inline void line_line_distance_gradient(
    const Vec3<T>& ea0, const Vec3<T>& ea1, const Vec3<T>& eb0, const Vec3<T>& eb1, T* g)
{
    T k[9], ky[9];
    distance_kernels::point_plane(ea0 - eb0, ea1 - ea0, eb1 - eb0, k, nullptr);
    line_line_detail::to_shared_vertex_gradient(k, ky);
    const int plus[3] = { 1, 2, 3 };
    distance_kernels::pull_back_gradient<3>(ky, plus, 0, g);
}

/// @brief Hessian of line_line_distance. @param H out: 12 x 12 row-major, ordered (ea0, ea1, eb0, eb1)
template <class T>
DIFFIPC_HD inline void line_line_distance_hessian(
    const Vec3<T>& ea0, const Vec3<T>& ea1, const Vec3<T>& eb0, const Vec3<T>& eb1, T* H)
{
    T k[81], ky[81];
    distance_kernels::point_plane(ea0 - eb0, ea1 - ea0, eb1 - eb0, nullptr, k);
    line_line_detail::to_shared_vertex_hessian(k, ky);
    const int plus[3] = { 1, 2, 3 };
    distance_kernels::pull_back_hessian<3>(ky, plus, 0, H);
}

} // namespace diffipc::kernels
