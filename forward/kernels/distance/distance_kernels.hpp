#pragma once
/// @file distance_kernels.hpp
/// The rational functions behind every squared distance, written in difference vectors
/// (r = p - e0, a = t1 - t0, ...), where their derivatives are short, and the maps that carry
/// those derivatives back to vertex-major coordinates. Internal to forward/kernels/distance
/// (include the distance headers instead).
///
/// Why difference vectors: every distance is translation invariant, so its vertex derivatives
/// are a fixed +-1 combination of the derivatives in 2 or 3 edge vectors. Differentiating in the
/// edge vectors keeps the closed forms small (the cross products stay intact, which also keeps
/// them accurate when the distance is tiny) and the pull-back is a handful of 3x3 block copies.
///
/// Layouts: K stacked difference vectors have a 3K gradient and a 3K by 3K Hessian, row-major
/// (H[r * 3K + c]); a pulled-back derivative is vertex-major over K + 1 vertices, xyz each.

#include "forward/kernels/vec3.hpp"

namespace diffipc::kernels::distance_kernels {

/// @brief Adds the cross-product matrix [v]x to the 3x3 block (i, j) of the row-major n by n
/// matrix H (so that [v]x w = v x w) and its transpose -[v]x to the block (j, i).
template <class T> DIFFIPC_HD inline void add_cross_matrix(T* H, int n, int i, int j, const Vec3<T>& v)
{
    H[(i + 0) * n + j + 1] -= v.z;
    H[(i + 0) * n + j + 2] += v.y;
    H[(i + 1) * n + j + 0] += v.z;
    H[(i + 1) * n + j + 2] -= v.x;
    H[(i + 2) * n + j + 0] -= v.y;
    H[(i + 2) * n + j + 1] += v.x;
    H[(j + 1) * n + i + 0] -= v.z;
    H[(j + 2) * n + i + 0] += v.y;
    H[(j + 0) * n + i + 1] += v.z;
    H[(j + 2) * n + i + 1] -= v.x;
    H[(j + 0) * n + i + 2] -= v.y;
    H[(j + 1) * n + i + 2] += v.x;
}

/// @brief \f$ |a \times b|^2 \f$ with gradient and Hessian in the stacked (a, b).
/// @param grad 6, or nullptr; @param hess 6 x 6 row-major, or nullptr
template <class T>
DIFFIPC_HD inline T cross_squarednorm(const Vec3<T>& a, const Vec3<T>& b, non_deduced<T>* grad, non_deduced<T>* hess)
{
    const Vec3<T> n = cross(a, b);
    if (grad) {
        // Written with n rather than as 2 a |b|^2 - 2 (a.b) b: the expanded form cancels
        // catastrophically when a and b are nearly parallel, exactly where the mollifier needs
        // this gradient.
        store(2.0 * cross(b, n), grad);
        store(2.0 * cross(n, a), grad + 3);
    }
    if (hess) {
        const T bb = squared_norm(b), aa = squared_norm(a), ab = dot(a, b);
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) {
                const T ai = component(a, i), aj = component(a, j);
                const T bi = component(b, i), bj = component(b, j);
                hess[i * 6 + j] = 2 * ((i == j ? bb : 0.0) - bi * bj);
                hess[(3 + i) * 6 + 3 + j] = 2 * ((i == j ? aa : 0.0) - ai * aj);
                // 4 a b^T - 2 b a^T - 2 (a.b) I, and its transpose below the diagonal
                const T v = (4 * ai) * bj - (2 * bi) * aj - (i == j ? 2 * ab : 0.0);
                hess[i * 6 + 3 + j] = v;
                hess[(3 + j) * 6 + i] = v;
            }
    }
    return squared_norm(n);
}

// d = N / D. Differentiating d D = N twice gives the quotient rule in the form used below:
//   grad d = (grad N - d grad D) / D,
//   hess d = (hess N - d hess D - grad d grad D^T - grad D grad d^T) / D.

/// @brief \f$ |r \times e|^2 / |e|^2 \f$ with derivatives in the stacked (r, e). Requires e != 0.
/// @param grad 6, or nullptr; @param hess 6 x 6 row-major, or nullptr
template <class T>
DIFFIPC_HD inline T point_line(const Vec3<T>& r, const Vec3<T>& e, non_deduced<T>* grad, non_deduced<T>* hess)
{
    T gN[6];
    const T N = cross_squarednorm(r, e, (grad || hess) ? gN : nullptr, hess);
    const T D = squared_norm(e);
    const T d = N / D;
    if (!grad && !hess)
        return d;
    // grad D = (0, 2 e), hess D = diag(0, 2 I).
    T gd[6];
    for (int k = 0; k < 6; ++k)
        gd[k] = gN[k];
    for (int i = 0; i < 3; ++i)
        gd[3 + i] -= 2 * d * component(e, i);
    for (int k = 0; k < 6; ++k)
        gd[k] /= D;
    if (grad)
        for (int k = 0; k < 6; ++k)
            grad[k] = gd[k];
    if (hess) {
        T* H = hess; // holds hess N
        for (int i = 0; i < 3; ++i)
            H[(3 + i) * 6 + 3 + i] -= 2 * d;
        // H.block<6, 3>(0, 3) -= gd (2 e)^T, then H.block<3, 6>(3, 0) -= (2 e) gd^T.
        for (int r = 0; r < 6; ++r)
            for (int j = 0; j < 3; ++j)
                H[r * 6 + 3 + j] -= gd[r] * (2 * component(e, j));
        for (int i = 0; i < 3; ++i)
            for (int c = 0; c < 6; ++c)
                H[(3 + i) * 6 + c] -= (2 * component(e, i)) * gd[c];
        for (int k = 0; k < 36; ++k)
            H[k] /= D;
    }
    return d;
}

/// @brief \f$ (r \cdot (a \times b))^2 / |a \times b|^2 \f$ with derivatives in the stacked
/// (r, a, b). Point-plane and line-line distances are both this function. Requires a x b != 0.
/// @param grad 9, or nullptr; @param hess 9 x 9 row-major, or nullptr
template <class T>
DIFFIPC_HD inline T point_plane(
    const Vec3<T>& r, const Vec3<T>& a, const Vec3<T>& b, non_deduced<T>* grad, non_deduced<T>* hess)
{
    // h = r . (a x b) is unchanged by removing r's component along a (n is orthogonal to a), and
    // the removal keeps h accurate for nearly parallel a and b: n = a x b is rounded by
    // ~eps |a| |b| in every direction, also within the plane of a and b, where r has an O(|r|)
    // component but r_perp only its offset across a, which is O(angle) wherever the closest
    // points lie inside both edges (where line-line is used). Dotting with r makes the relative
    // error of the distance grow like eps |r| / (distance angle); NearlyParallelLines in
    // tests/forward/kernels/distance/test_line_line.cpp checks the value.
    const T alpha = dot(r, a) / squared_norm(a);
    const Vec3<T> r_perp = r - alpha * a;
    const Vec3<T> n = cross(a, b);
    const T D = squared_norm(n);
    const T h = dot(r_perp, n); // triple product [r, a, b]
    const T d = h * h / D;
    if (!grad && !hess)
        return d;

    T gh[9]; // gradient of the triple product
    store(n, gh);
    store(cross(b, r_perp) - alpha * n, gh + 3);
    store(cross(r_perp, a), gh + 6);
    T gD_ab[6];
    T HD_ab[36];
    cross_squarednorm(a, b, gD_ab, hess ? HD_ab : nullptr);

    // D does not depend on r. With the quotient rule above and
    // grad d = (2 h grad h - d grad D) / D substituted, the Hessian collapses to
    //   hess d = (2 / D) y y^T + (2 h hess h - d hess D) / D,  y = grad h - (h / D) grad D,
    // one outer product instead of three.
    if (grad) {
        for (int k = 0; k < 9; ++k)
            grad[k] = (2 * h / D) * gh[k];
        for (int k = 0; k < 6; ++k)
            grad[3 + k] -= (d / D) * gD_ab[k];
    }
    if (hess) {
        T y[9];
        for (int k = 0; k < 9; ++k)
            y[k] = gh[k];
        for (int k = 0; k < 6; ++k)
            y[3 + k] -= (h / D) * gD_ab[k];
        T* H = hess;
        for (int i = 0; i < 9; ++i)
            for (int j = 0; j < 9; ++j)
                H[i * 9 + j] = ((2 / D) * y[i]) * y[j];
        // The triple product is trilinear: d2h/dr da = -[b]x, d2h/dr db = [a]x, d2h/da db = -[r]x.
        const T c = 2 * h / D;
        add_cross_matrix(H, 9, 0, 3, -c * b);
        add_cross_matrix(H, 9, 0, 6, c * a);
        add_cross_matrix(H, 9, 3, 6, -c * r);
        for (int i = 0; i < 6; ++i)
            for (int j = 0; j < 6; ++j)
                H[(3 + i) * 9 + 3 + j] -= (d / D) * HD_ab[i * 6 + j];
    }
    return d;
}

/// @brief Chain rule for kernel variables that share one vertex, x_k = X[plus[k]] - X[minus]
/// (k < K, K + 1 vertices X): the 3(K+1) gradient.
/// @param g 3K, @param out 3(K+1)
template <int K, class T> DIFFIPC_HD inline void pull_back_gradient(const T* g, const int* plus, int minus, T* out)
{
    T sum[3] = { 0, 0, 0 };
    for (int k = 0; k < K; ++k)
        for (int i = 0; i < 3; ++i) {
            out[3 * plus[k] + i] = g[3 * k + i];
            sum[i] += g[3 * k + i];
        }
    for (int i = 0; i < 3; ++i)
        out[3 * minus + i] = -sum[i];
}

/// @brief Chain rule for kernel variables that share one vertex (see pull_back_gradient): the
/// 3(K+1) by 3(K+1) Hessian J^T H J. Every output block is written once, which measured 2-3x
/// faster than accumulating +-H blocks into a zeroed matrix (this runs for every contact).
/// @param H 3K by 3K row-major, @param out 3(K+1) by 3(K+1) row-major
template <int K, class T> DIFFIPC_HD inline void pull_back_hessian(const T* H, const int* plus, int minus, T* out)
{
    constexpr int n = 3 * K, m = 3 * (K + 1);
    T row_sums[n * 3]; // row_sums(r, j) = sum_l H(r, 3 l + j), l increasing
    for (int k = 0; k < n * 3; ++k)
        row_sums[k] = 0;
    for (int l = 0; l < K; ++l)
        for (int r = 0; r < n; ++r)
            for (int j = 0; j < 3; ++j)
                row_sums[r * 3 + j] += H[r * n + 3 * l + j];
    T total[9] = { 0, 0, 0, 0, 0, 0, 0, 0, 0 };
    for (int k = 0; k < K; ++k) {
        for (int l = 0; l < K; ++l)
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    out[(3 * plus[k] + i) * m + 3 * plus[l] + j] = H[(3 * k + i) * n + 3 * l + j];
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) {
                const T S = row_sums[(3 * k + i) * 3 + j];
                out[(3 * plus[k] + i) * m + 3 * minus + j] = -S;
                out[(3 * minus + j) * m + 3 * plus[k] + i] = -S;
                total[i * 3 + j] += S;
            }
    }
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            out[(3 * minus + i) * m + 3 * minus + j] = total[i * 3 + j];
}

/// @brief Places the 3L gradient of a sub-distance on L of the V vertices (ids), zeros elsewhere.
/// @param g 3L, @param out 3V
template <int V, int L, class T> DIFFIPC_HD inline void scatter_gradient(const T* g, const int* ids, T* out)
{
    for (int k = 0; k < 3 * V; ++k)
        out[k] = 0;
    for (int a = 0; a < L; ++a)
        for (int i = 0; i < 3; ++i)
            out[3 * ids[a] + i] = g[3 * a + i];
}

/// @brief Places the 3L by 3L Hessian of a sub-distance on L of the V vertices (ids), zeros elsewhere.
/// @param H 3L by 3L row-major, @param out 3V by 3V row-major
template <int V, int L, class T> DIFFIPC_HD inline void scatter_hessian(const T* H, const int* ids, T* out)
{
    constexpr int n = 3 * L, m = 3 * V;
    for (int k = 0; k < m * m; ++k)
        out[k] = 0;
    for (int a = 0; a < L; ++a)
        for (int b = 0; b < L; ++b)
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    out[(3 * ids[a] + i) * m + 3 * ids[b] + j] = H[(3 * a + i) * n + 3 * b + j];
}

} // namespace diffipc::kernels::distance_kernels
