#pragma once
/// @file distance_kernels.cuh
/// Host and device port of forward/contact/distance/distance_kernels: the rational functions
/// behind every squared distance, in difference vectors (r = p - e0, a = t1 - t0, ...), and the
/// maps that carry their derivatives back to vertex-major coordinates. Every expression is the
/// CPU's, evaluated in the CPU's order (vec3.cuh rounds like Eigen::Vector3d, products of a
/// scaled vector and a transposed vector like Eigen's outer products), so that the host build of
/// this header gives the CPU's values bit for bit.
///
/// Layouts: K stacked difference vectors have a 3K gradient and a 3K by 3K Hessian, row-major
/// (H[r * 3K + c]); a pulled-back derivative is vertex-major over K + 1 vertices, xyz each.
/// Internal to cuda/contact/distance (include the distance headers instead).

#include "cuda/common/vec3.cuh"

namespace diffipc::gpu::distance_kernels {

/// Component i (0, 1, 2) of v.
DIFFIPC_HD inline double component(const vec3& v, int i) { return i == 0 ? v.x : i == 1 ? v.y : v.z; }

/// Writes v into g[0..2].
DIFFIPC_HD inline void store(const vec3& v, double* g)
{
    g[0] = v.x;
    g[1] = v.y;
    g[2] = v.z;
}

/// @brief Adds the cross-product matrix [v]x to the 3x3 block (i, j) of the row-major n by n
/// matrix H and its transpose -[v]x to the block (j, i) (the CPU's add_cross_matrix).
DIFFIPC_HD inline void add_cross_matrix(double* H, int n, int i, int j, const vec3& v)
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
DIFFIPC_HD inline double cross_squarednorm(const vec3& a, const vec3& b, double* grad, double* hess)
{
    const vec3 n = cross(a, b);
    if (grad) {
        // With n rather than 2 a |b|^2 - 2 (a.b) b, which cancels for nearly parallel a and b.
        store(2.0 * cross(b, n), grad);
        store(2.0 * cross(n, a), grad + 3);
    }
    if (hess) {
        const double bb = squared_norm(b), aa = squared_norm(a), ab = dot(a, b);
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) {
                const double ai = component(a, i), aj = component(a, j);
                const double bi = component(b, i), bj = component(b, j);
                hess[i * 6 + j] = 2 * ((i == j ? bb : 0.0) - bi * bj);
                hess[(3 + i) * 6 + 3 + j] = 2 * ((i == j ? aa : 0.0) - ai * aj);
                // 4 a b^T - 2 b a^T - 2 (a.b) I, and its transpose below the diagonal
                const double v = (4 * ai) * bj - (2 * bi) * aj - (i == j ? 2 * ab : 0.0);
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
DIFFIPC_HD inline double point_line(const vec3& r, const vec3& e, double* grad, double* hess)
{
    double gN[6];
    const double N = cross_squarednorm(r, e, (grad || hess) ? gN : nullptr, hess);
    const double D = squared_norm(e);
    const double d = N / D;
    if (!grad && !hess)
        return d;
    // grad D = (0, 2 e), hess D = diag(0, 2 I).
    double gd[6];
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
        double* H = hess; // holds hess N
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
DIFFIPC_HD inline double point_plane(const vec3& r, const vec3& a, const vec3& b, double* grad, double* hess)
{
    // h = r . (a x b) with r's component along a removed, which keeps h accurate for nearly
    // parallel a and b (the CPU kernel says why).
    const double alpha = dot(r, a) / squared_norm(a);
    const vec3 r_perp = r - alpha * a;
    const vec3 n = cross(a, b);
    const double D = squared_norm(n);
    const double h = dot(r_perp, n); // triple product [r, a, b]
    const double d = h * h / D;
    if (!grad && !hess)
        return d;

    double gh[9]; // gradient of the triple product
    store(n, gh);
    store(cross(b, r_perp) - alpha * n, gh + 3);
    store(cross(r_perp, a), gh + 6);
    double gD_ab[6];
    double HD_ab[36];
    cross_squarednorm(a, b, gD_ab, hess ? HD_ab : nullptr);

    // hess d = (2 / D) y y^T + (2 h hess h - d hess D) / D,  y = grad h - (h / D) grad D.
    if (grad) {
        for (int k = 0; k < 9; ++k)
            grad[k] = (2 * h / D) * gh[k];
        for (int k = 0; k < 6; ++k)
            grad[3 + k] -= (d / D) * gD_ab[k];
    }
    if (hess) {
        double y[9];
        for (int k = 0; k < 9; ++k)
            y[k] = gh[k];
        for (int k = 0; k < 6; ++k)
            y[3 + k] -= (h / D) * gD_ab[k];
        double* H = hess;
        for (int i = 0; i < 9; ++i)
            for (int j = 0; j < 9; ++j)
                H[i * 9 + j] = ((2 / D) * y[i]) * y[j];
        // The triple product is trilinear: d2h/dr da = -[b]x, d2h/dr db = [a]x, d2h/da db = -[r]x.
        const double c = 2 * h / D;
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
/// (k < K, K + 1 vertices X): the 3(K+1) gradient (the CPU's pull_back_gradient).
/// @param g 3K, @param out 3(K+1)
template <int K> DIFFIPC_HD inline void pull_back_gradient(const double* g, const int* plus, int minus, double* out)
{
    double sum[3] = { 0, 0, 0 };
    for (int k = 0; k < K; ++k)
        for (int i = 0; i < 3; ++i) {
            out[3 * plus[k] + i] = g[3 * k + i];
            sum[i] += g[3 * k + i];
        }
    for (int i = 0; i < 3; ++i)
        out[3 * minus + i] = -sum[i];
}

/// @brief Chain rule for kernel variables that share one vertex (see pull_back_gradient): the
/// 3(K+1) by 3(K+1) Hessian J^T H J, every block written once (the CPU's pull_back_hessian).
/// @param H 3K by 3K row-major, @param out 3(K+1) by 3(K+1) row-major
template <int K> DIFFIPC_HD inline void pull_back_hessian(const double* H, const int* plus, int minus, double* out)
{
    constexpr int n = 3 * K, m = 3 * (K + 1);
    double row_sums[n * 3]; // row_sums(r, j) = sum_l H(r, 3 l + j), l increasing
    for (int k = 0; k < n * 3; ++k)
        row_sums[k] = 0;
    for (int l = 0; l < K; ++l)
        for (int r = 0; r < n; ++r)
            for (int j = 0; j < 3; ++j)
                row_sums[r * 3 + j] += H[r * n + 3 * l + j];
    double total[9] = { 0, 0, 0, 0, 0, 0, 0, 0, 0 };
    for (int k = 0; k < K; ++k) {
        for (int l = 0; l < K; ++l)
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    out[(3 * plus[k] + i) * m + 3 * plus[l] + j] = H[(3 * k + i) * n + 3 * l + j];
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) {
                const double S = row_sums[(3 * k + i) * 3 + j];
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
template <int V, int L> DIFFIPC_HD inline void scatter_gradient(const double* g, const int* ids, double* out)
{
    for (int k = 0; k < 3 * V; ++k)
        out[k] = 0;
    for (int a = 0; a < L; ++a)
        for (int i = 0; i < 3; ++i)
            out[3 * ids[a] + i] = g[3 * a + i];
}

/// @brief Places the 3L by 3L Hessian of a sub-distance on L of the V vertices (ids), zeros elsewhere.
/// @param H 3L by 3L row-major, @param out 3V by 3V row-major
template <int V, int L> DIFFIPC_HD inline void scatter_hessian(const double* H, const int* ids, double* out)
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

} // namespace diffipc::gpu::distance_kernels
