#pragma once
/// @file edge_edge_mollifier.hpp
/// IPC's edge-edge mollifier (Li et al. 2020, "Incremental Potential Contact", the mollified
/// edge-edge barrier), which multiplies the barrier of an edge-edge pair and vanishes as the edges
/// become parallel. There the edge-edge distance is not smooth (the closest points jump along the
/// edges and the line-line derivatives blow up like 1/angle^2); the product m * b stays C1.
/// \f[ x = |(e_{a1} - e_{a0}) \times (e_{b1} - e_{b0})|^2, \qquad
///     \epsilon_x = 10^{-3} |\bar e_{a1} - \bar e_{a0}|^2 |\bar e_{b1} - \bar e_{b0}|^2, \f]
/// \f[ m(x) = (2 - s)\, s \text{ for } s = x / \epsilon_x < 1, \qquad m(x) = 1 \text{ otherwise,} \f]
/// the bars denoting REST positions: eps_x is a constant of the pair during a simulation, but a
/// function of the rest shape in shape optimization, hence the derivatives with respect to eps_x.
/// m is C1 (not C2) at x = eps_x: m'' jumps from -2/eps_x^2 to 0. eps_x <= 0 (a degenerate rest
/// edge) gives m = 1 and zero derivatives. Vectors are vertex-major over (ea0, ea1, eb0, eb1),
/// xyz per vertex; Hessians row-major.

#include "forward/kernels/distance/distance_kernels.hpp"

namespace diffipc::kernels {

namespace edge_edge_mollifier_detail {
    // Kernel variables a = ea1 - ea0, b = eb1 - eb0, rewritten for the pull-back in variables
    // sharing ea0: y1 = ea1 - ea0, y2 = eb0 - ea0, y3 = eb1 - ea0, i.e. (a, b) = (y1, y3 - y2).

    /// @param g 6 in (a, b), @param out 12
    template <class T> DIFFIPC_HD inline void pull_back_gradient(const T* g, T* out)
    {
        T gy[9];
        for (int i = 0; i < 3; ++i) {
            gy[i] = g[i];
            gy[3 + i] = -g[3 + i];
            gy[6 + i] = g[3 + i];
        }
        const int plus[3] = { 1, 2, 3 };
        distance_kernels::pull_back_gradient<3>(gy, plus, 0, out);
    }

    /// @param H 6 x 6 row-major in (a, b), @param out 12 x 12 row-major
    template <class T> DIFFIPC_HD inline void pull_back_hessian(const T* H, T* out)
    {
        // Hy = [[Haa, -Hab, Hab], [-Hab^T, Hbb, -Hbb], [Hab^T, -Hbb, Hbb]]
        T Hy[81];
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) {
                const T aa = H[i * 6 + j], ab = H[i * 6 + 3 + j], ba = H[j * 6 + 3 + i];
                const T bb = H[(3 + i) * 6 + 3 + j];
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

    /// IPC's choice (Li et al. 2020): the mollifier acts below 0.1% of the rest cross product's
    /// squared norm, i.e. below an angle of ~1.8 degrees.
    constexpr double MOLLIFIER_THRESHOLD_SCALE = 1e-3;
} // namespace edge_edge_mollifier_detail

/// @brief \f$ x = |(e_{a1} - e_{a0}) \times (e_{b1} - e_{b0})|^2 \f$ (m^4).
template <class T>
DIFFIPC_HD inline T edge_edge_cross_squarednorm(
    const Vec3<T>& ea0, const Vec3<T>& ea1, const Vec3<T>& eb0, const Vec3<T>& eb1)
{
    return squared_norm(cross(ea1 - ea0, eb1 - eb0));
}

/// @brief Gradient of edge_edge_cross_squarednorm. @param g out: 12, m^3
template <class T>
DIFFIPC_HD inline void edge_edge_cross_squarednorm_gradient(
    const Vec3<T>& ea0, const Vec3<T>& ea1, const Vec3<T>& eb0, const Vec3<T>& eb1, T* g)
{
    T k[6];
    distance_kernels::cross_squarednorm(ea1 - ea0, eb1 - eb0, k, nullptr);
    edge_edge_mollifier_detail::pull_back_gradient(k, g);
}

/// @brief Hessian of edge_edge_cross_squarednorm. @param H out: 12 x 12 row-major, m^2
template <class T>
DIFFIPC_HD inline void edge_edge_cross_squarednorm_hessian(
    const Vec3<T>& ea0, const Vec3<T>& ea1, const Vec3<T>& eb0, const Vec3<T>& eb1, T* H)
{
    T k[36];
    distance_kernels::cross_squarednorm(ea1 - ea0, eb1 - eb0, nullptr, k);
    edge_edge_mollifier_detail::pull_back_hessian(k, H);
}

/// @brief eps_x of an edge pair at its rest positions (m^4).
template <class T>
DIFFIPC_HD inline T edge_edge_mollifier_threshold(
    const Vec3<T>& ea0_rest, const Vec3<T>& ea1_rest, const Vec3<T>& eb0_rest, const Vec3<T>& eb1_rest)
{
    return edge_edge_mollifier_detail::MOLLIFIER_THRESHOLD_SCALE * squared_norm(ea1_rest - ea0_rest)
        * squared_norm(eb1_rest - eb0_rest);
}

/// @brief Gradient of edge_edge_mollifier_threshold with respect to the rest positions (shape
/// derivatives), e.g. d eps_x / d ea1_rest = 2e-3 |b|^2 a with a = ea1_rest - ea0_rest.
/// @param g out: 12 (d/dea0_rest, d/dea1_rest, d/deb0_rest, d/deb1_rest), m^3
template <class T>
DIFFIPC_HD inline void edge_edge_mollifier_threshold_gradient(
    const Vec3<T>& ea0_rest, const Vec3<T>& ea1_rest, const Vec3<T>& eb0_rest, const Vec3<T>& eb1_rest, T* g)
{
    const Vec3<T> a = ea1_rest - ea0_rest, b = eb1_rest - eb0_rest;
    constexpr double c = 2 * edge_edge_mollifier_detail::MOLLIFIER_THRESHOLD_SCALE;
    T k[6];
    store((c * squared_norm(b)) * a, k);
    store((c * squared_norm(a)) * b, k + 3);
    edge_edge_mollifier_detail::pull_back_gradient(k, g);
}

// Each scalar form is a polynomial in s = x / eps_x in [0, 1) over a power of eps_x, as in the
// paper; `!(x < eps_x)` also sends eps_x <= 0 and NaN to the unmollified branch instead of
// dividing by zero.

/// @brief m(x) in [0, 1].
template <class T> DIFFIPC_HD inline T edge_edge_mollifier(T x, T eps_x)
{
    if (!(x < eps_x))
        return 1;
    const T s = x / eps_x;
    return (2 - s) * s;
}

/// @brief dm/dx = 2 (1 - x/eps_x) / eps_x for x < eps_x, else 0 (m^-4).
template <class T> DIFFIPC_HD inline T edge_edge_mollifier_gradient(T x, T eps_x)
{
    if (!(x < eps_x))
        return 0;
    return 2 * (1 - x / eps_x) / eps_x;
}

/// @brief d^2m/dx^2 = -2 / eps_x^2 for x < eps_x, else 0 (m^-8).
template <class T> DIFFIPC_HD inline T edge_edge_mollifier_hessian(T x, T eps_x)
{
    if (!(x < eps_x))
        return 0;
    return -2 / (eps_x * eps_x);
}

/// @brief dm/d eps_x = -2 (x/eps_x)(1 - x/eps_x) / eps_x for x < eps_x, else 0 (m^-4). Never
/// positive: a larger threshold mollifies more.
template <class T> DIFFIPC_HD inline T edge_edge_mollifier_gradient_wrt_eps_x(T x, T eps_x)
{
    if (!(x < eps_x))
        return 0;
    const T s = x / eps_x;
    return -2 * s * (1 - s) / eps_x;
}

/// @brief d^2m/(dx d eps_x) = 2 (2 x/eps_x - 1) / eps_x^2 for x < eps_x, else 0 (m^-8).
template <class T> DIFFIPC_HD inline T edge_edge_mollifier_gradient_jacobian_wrt_eps_x(T x, T eps_x)
{
    if (!(x < eps_x))
        return 0;
    return 2 * (2 * (x / eps_x) - 1) / (eps_x * eps_x);
}

/// @brief The mollifier of the edge pair at its current positions, m(x(ea0, ea1, eb0, eb1)).
template <class T>
DIFFIPC_HD inline T edge_edge_mollifier(
    const Vec3<T>& ea0, const Vec3<T>& ea1, const Vec3<T>& eb0, const Vec3<T>& eb1, T eps_x)
{
    return edge_edge_mollifier(edge_edge_cross_squarednorm(ea0, ea1, eb0, eb1), eps_x);
}

namespace edge_edge_mollifier_detail {
    /// c(x) grad x for x < eps_x, zeros otherwise, with c = dm/dx (wrt_eps_x false) or
    /// d^2m/(dx d eps_x) (true): the shape of both position gradients.
    template <class T>
    DIFFIPC_HD inline void factor_times_cross_gradient(
        const Vec3<T>& ea0, const Vec3<T>& ea1, const Vec3<T>& eb0, const Vec3<T>& eb1, T eps_x, bool wrt_eps_x, T* g)
    {
        const T x = edge_edge_cross_squarednorm(ea0, ea1, eb0, eb1);
        if (!(x < eps_x)) { // the common case: skip the cross product's gradient
            for (int k = 0; k < 12; ++k)
                g[k] = 0;
            return;
        }
        const T c = wrt_eps_x ? edge_edge_mollifier_gradient_jacobian_wrt_eps_x(x, eps_x)
                              : edge_edge_mollifier_gradient(x, eps_x);
        T gx[12];
        edge_edge_cross_squarednorm_gradient(ea0, ea1, eb0, eb1, gx);
        for (int k = 0; k < 12; ++k)
            g[k] = c * gx[k];
    }
} // namespace edge_edge_mollifier_detail

/// @brief m'(x) grad x. @param g out: 12, m^-1
template <class T>
DIFFIPC_HD inline void edge_edge_mollifier_gradient(
    const Vec3<T>& ea0, const Vec3<T>& ea1, const Vec3<T>& eb0, const Vec3<T>& eb1, T eps_x, T* g)
{
    edge_edge_mollifier_detail::factor_times_cross_gradient(ea0, ea1, eb0, eb1, eps_x, false, g);
}

/// @brief m''(x) grad x grad x^T + m'(x) hess x. @param H out: 12 x 12 row-major, m^-2
template <class T>
DIFFIPC_HD inline void edge_edge_mollifier_hessian(
    const Vec3<T>& ea0, const Vec3<T>& ea1, const Vec3<T>& eb0, const Vec3<T>& eb1, T eps_x, T* H)
{
    T g[6], Hx[36];
    const T x = distance_kernels::cross_squarednorm(ea1 - ea0, eb1 - eb0, g, Hx);
    if (!(x < eps_x)) {
        for (int k = 0; k < 144; ++k)
            H[k] = 0;
        return;
    }
    const T m2 = edge_edge_mollifier_hessian(x, eps_x), m1 = edge_edge_mollifier_gradient(x, eps_x);
    T Hm[36];
    for (int i = 0; i < 6; ++i)
        for (int j = 0; j < 6; ++j)
            Hm[i * 6 + j] = (m2 * g[i]) * g[j] + m1 * Hx[i * 6 + j];
    edge_edge_mollifier_detail::pull_back_hessian(Hm, H);
}

/// @brief d^2m/(dx d eps_x) grad x: the derivative of the position gradient with respect to eps_x.
/// @param g out: 12, m^-5
template <class T>
DIFFIPC_HD inline void edge_edge_mollifier_gradient_jacobian_wrt_eps_x(
    const Vec3<T>& ea0, const Vec3<T>& ea1, const Vec3<T>& eb0, const Vec3<T>& eb1, T eps_x, T* g)
{
    edge_edge_mollifier_detail::factor_times_cross_gradient(ea0, ea1, eb0, eb1, eps_x, true, g);
}

} // namespace diffipc::kernels
