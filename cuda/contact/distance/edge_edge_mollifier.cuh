#pragma once
/// @file edge_edge_mollifier.cuh
/// Host and device port of forward/contact/distance/edge_edge_mollifier: IPC's edge-edge
/// mollifier (Li et al. 2020, "Incremental Potential Contact"), which multiplies the barrier of
/// an edge-edge pair and vanishes as the edges become parallel:
/// \f[ x = |(e_{a1} - e_{a0}) \times (e_{b1} - e_{b0})|^2, \qquad
///     \epsilon_x = 10^{-3} |\bar e_{a1} - \bar e_{a0}|^2 |\bar e_{b1} - \bar e_{b0}|^2, \f]
/// \f[ m(x) = (2 - s)\, s \text{ for } s = x / \epsilon_x < 1, \qquad m(x) = 1 \text{ otherwise,} \f]
/// the bars denoting rest positions. eps_x <= 0 (a degenerate rest edge) gives m = 1 and zero
/// derivatives. Vectors are vertex-major over (ea0, ea1, eb0, eb1), xyz per vertex; Hessians
/// row-major. (The shape-derivative functions of the CPU file are not ported: the GPU has no
/// adjoint yet.)

#include "cuda/contact/distance/distance_kernels.cuh"

namespace diffipc::gpu {

namespace edge_edge_mollifier_detail {
    // Kernel variables a = ea1 - ea0, b = eb1 - eb0, rewritten for the pull-back in variables
    // sharing ea0: y1 = ea1 - ea0, y2 = eb0 - ea0, y3 = eb1 - ea0, i.e. (a, b) = (y1, y3 - y2).

    /// @param g 6 in (a, b), @param out 12
    DIFFIPC_HD inline void pull_back_gradient(const double* g, double* out)
    {
        double gy[9];
        for (int i = 0; i < 3; ++i) {
            gy[i] = g[i];
            gy[3 + i] = -g[3 + i];
            gy[6 + i] = g[3 + i];
        }
        const int plus[3] = { 1, 2, 3 };
        distance_kernels::pull_back_gradient<3>(gy, plus, 0, out);
    }

    /// @param H 6 x 6 row-major in (a, b), @param out 12 x 12 row-major
    DIFFIPC_HD inline void pull_back_hessian(const double* H, double* out)
    {
        // Hy = [[Haa, -Hab, Hab], [-Hab^T, Hbb, -Hbb], [Hab^T, -Hbb, Hbb]]
        double Hy[81];
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) {
                const double aa = H[i * 6 + j], ab = H[i * 6 + 3 + j], ba = H[j * 6 + 3 + i];
                const double bb = H[(3 + i) * 6 + 3 + j];
                Hy[(0 + i) * 9 + 0 + j] = aa;
                Hy[(0 + i) * 9 + 3 + j] = -ab;
                Hy[(0 + i) * 9 + 6 + j] = ab;
                Hy[(3 + i) * 9 + 0 + j] = -ba;
                Hy[(3 + i) * 9 + 3 + j] = bb;
                Hy[(3 + i) * 9 + 6 + j] = -bb;
                Hy[(6 + i) * 9 + 0 + j] = ba;
                Hy[(6 + i) * 9 + 3 + j] = -bb;
                Hy[(6 + i) * 9 + 6 + j] = bb;
            }
        const int plus[3] = { 1, 2, 3 };
        distance_kernels::pull_back_hessian<3>(Hy, plus, 0, out);
    }

    /// IPC's choice: the mollifier acts below 0.1% of the rest cross product's squared norm.
    constexpr double MOLLIFIER_THRESHOLD_SCALE = 1e-3;
} // namespace edge_edge_mollifier_detail

/// @brief \f$ x = |(e_{a1} - e_{a0}) \times (e_{b1} - e_{b0})|^2 \f$ (m^4).
DIFFIPC_HD inline double edge_edge_cross_squarednorm(const vec3& ea0, const vec3& ea1, const vec3& eb0, const vec3& eb1)
{
    return squared_norm(cross(ea1 - ea0, eb1 - eb0));
}

/// @brief Gradient of edge_edge_cross_squarednorm. @param g out: 12, m^3
DIFFIPC_HD inline void edge_edge_cross_squarednorm_gradient(
    const vec3& ea0, const vec3& ea1, const vec3& eb0, const vec3& eb1, double* g)
{
    double k[6];
    distance_kernels::cross_squarednorm(ea1 - ea0, eb1 - eb0, k, nullptr);
    edge_edge_mollifier_detail::pull_back_gradient(k, g);
}

/// @brief Hessian of edge_edge_cross_squarednorm. @param H out: 12 x 12 row-major, m^2
DIFFIPC_HD inline void edge_edge_cross_squarednorm_hessian(
    const vec3& ea0, const vec3& ea1, const vec3& eb0, const vec3& eb1, double* H)
{
    double k[36];
    distance_kernels::cross_squarednorm(ea1 - ea0, eb1 - eb0, nullptr, k);
    edge_edge_mollifier_detail::pull_back_hessian(k, H);
}

/// @brief eps_x of an edge pair at its rest positions (m^4).
DIFFIPC_HD inline double edge_edge_mollifier_threshold(
    const vec3& ea0_rest, const vec3& ea1_rest, const vec3& eb0_rest, const vec3& eb1_rest)
{
    return edge_edge_mollifier_detail::MOLLIFIER_THRESHOLD_SCALE * squared_norm(ea1_rest - ea0_rest)
        * squared_norm(eb1_rest - eb0_rest);
}

// `!(x < eps_x)` also sends eps_x <= 0 and NaN to the unmollified branch.

/// @brief m(x) in [0, 1].
DIFFIPC_HD inline double edge_edge_mollifier(double x, double eps_x)
{
    if (!(x < eps_x))
        return 1;
    const double s = x / eps_x;
    return (2 - s) * s;
}

/// @brief dm/dx = 2 (1 - x/eps_x) / eps_x for x < eps_x, else 0 (m^-4).
DIFFIPC_HD inline double edge_edge_mollifier_gradient(double x, double eps_x)
{
    if (!(x < eps_x))
        return 0;
    return 2 * (1 - x / eps_x) / eps_x;
}

/// @brief d^2m/dx^2 = -2 / eps_x^2 for x < eps_x, else 0 (m^-8).
DIFFIPC_HD inline double edge_edge_mollifier_hessian(double x, double eps_x)
{
    if (!(x < eps_x))
        return 0;
    return -2 / (eps_x * eps_x);
}

/// @brief The mollifier of the edge pair at its current positions, m(x(ea0, ea1, eb0, eb1)).
DIFFIPC_HD inline double edge_edge_mollifier(
    const vec3& ea0, const vec3& ea1, const vec3& eb0, const vec3& eb1, double eps_x)
{
    return edge_edge_mollifier(edge_edge_cross_squarednorm(ea0, ea1, eb0, eb1), eps_x);
}

/// @brief m'(x) grad x. @param g out: 12, m^-1
DIFFIPC_HD inline void edge_edge_mollifier_gradient(
    const vec3& ea0, const vec3& ea1, const vec3& eb0, const vec3& eb1, double eps_x, double* g)
{
    const double x = edge_edge_cross_squarednorm(ea0, ea1, eb0, eb1);
    if (!(x < eps_x)) {
        for (int k = 0; k < 12; ++k)
            g[k] = 0;
        return;
    }
    const double dm = edge_edge_mollifier_gradient(x, eps_x);
    double gx[12];
    edge_edge_cross_squarednorm_gradient(ea0, ea1, eb0, eb1, gx);
    for (int k = 0; k < 12; ++k)
        g[k] = dm * gx[k];
}

/// @brief m''(x) grad x grad x^T + m'(x) hess x. @param H out: 12 x 12 row-major, m^-2
DIFFIPC_HD inline void edge_edge_mollifier_hessian(
    const vec3& ea0, const vec3& ea1, const vec3& eb0, const vec3& eb1, double eps_x, double* H)
{
    double g[6], Hx[36];
    const double x = distance_kernels::cross_squarednorm(ea1 - ea0, eb1 - eb0, g, Hx);
    if (!(x < eps_x)) {
        for (int k = 0; k < 144; ++k)
            H[k] = 0;
        return;
    }
    const double m2 = edge_edge_mollifier_hessian(x, eps_x), m1 = edge_edge_mollifier_gradient(x, eps_x);
    double Hm[36];
    for (int i = 0; i < 6; ++i)
        for (int j = 0; j < 6; ++j)
            Hm[i * 6 + j] = (m2 * g[i]) * g[j] + m1 * Hx[i * 6 + j];
    edge_edge_mollifier_detail::pull_back_hessian(Hm, H);
}

} // namespace diffipc::gpu
