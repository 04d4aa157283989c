#pragma once
/// @file inversion_bound.hpp
/// The inversion bound of a Newton step for one P1 element, on the host and the device: the signed
/// volume along x + t p as a polynomial in t, and the first t at which it falls to a fraction of
/// its start (root bracketing between the critical points, then bisection). The CPU's
/// inversion_free_step (forward/fem/fe_space.cpp) and the GPU's line search
/// (cuda/solver/device_newton.cu) take the minimum of element_step_bound over the elements, so
/// both start their line search from the same step length. A bound, not differentiated: written
/// on doubles.
///
/// Layouts: xe and pe are an element's (dim+1) vertex positions and step components, flattened
/// vertex-major (xe[a dim + i], a the element's local vertex, i the axis), in metres.

#include "forward/kernels/small_matrix.hpp"

namespace diffipc::kernels {

/// @brief The t-coefficient of det(P + t Q) for row-major 3x3 P, Q: the sum over columns k of
/// Q_k . (P_{k+1} x P_{k+2}) (in Eigen's cross and dot orders, as the CPU's code had it).
DIFFIPC_HD inline double mixed_coefficient(const double* P, const double* Q)
{
    double s = 0;
    for (int k = 0; k < 3; ++k) {
        const int k1 = (k + 1) % 3, k2 = (k + 2) % 3;
        const double p1[3] = { P[k1], P[3 + k1], P[6 + k1] }, p2[3] = { P[k2], P[3 + k2], P[6 + k2] };
        const double cr[3]
            = { p1[1] * p2[2] - p1[2] * p2[1], p1[2] * p2[0] - p1[0] * p2[2], p1[0] * p2[1] - p1[1] * p2[0] };
        s += Q[k] * cr[0] + Q[3 + k] * cr[1] + Q[6 + k] * cr[2];
    }
    return s;
}

/// @brief Coefficients c0..c3 of det[Ds(x + t p)] (dim! times the signed volume) as a polynomial in t:
/// quadratic in 2D (c3 = 0), cubic in 3D.
template <int dim> DIFFIPC_HD inline void volume_polynomial(const double* xe, const double* pe, double* c)
{
    if constexpr (dim == 2) {
        double u[2], v[2], du[2], dv[2];
        for (int i = 0; i < 2; ++i) {
            u[i] = xe[2 + i] - xe[i];
            v[i] = xe[4 + i] - xe[i];
            du[i] = pe[2 + i] - pe[i];
            dv[i] = pe[4 + i] - pe[i];
        }
        c[0] = u[0] * v[1] - u[1] * v[0];
        c[1] = u[0] * dv[1] + du[0] * v[1] - u[1] * dv[0] - du[1] * v[0];
        c[2] = du[0] * dv[1] - du[1] * dv[0];
        c[3] = 0.0;
    } else {
        // Row-major A(i, a) = x_{a+1,i} - x_{0,i}, B likewise for p (columns are the edge vectors).
        double A[9], B[9];
        for (int a = 0; a < 3; ++a)
            for (int i = 0; i < 3; ++i) {
                A[i * 3 + a] = xe[(a + 1) * 3 + i] - xe[i];
                B[i * 3 + a] = pe[(a + 1) * 3 + i] - pe[i];
            }
        c[0] = determinant<3>(A);
        c[1] = mixed_coefficient(A, B);
        c[2] = mixed_coefficient(B, A);
        c[3] = determinant<3>(B);
    }
}

/// ((c3 t + c2) t + c1) t + c0
DIFFIPC_HD inline double eval_cubic(const double* c, double t) { return ((c[3] * t + c[2]) * t + c[1]) * t + c[0]; }

/// @brief First t in (0, 1] where q(t) = c(t) - target <= 0, or 1 if none; returns a t at which
/// q(t) > 0. The critical points of q (roots of q'(t) = q1 + 2 q2 t + 3 q3 t^2 in (0, 1)) split
/// [0, 1] into monotone pieces; the first piece that ends with q <= 0 is bisected.
DIFFIPC_HD inline double first_crossing(const double* c, double target)
{
    const double q[4] = { c[0] - target, c[1], c[2], c[3] };
    double breaks[4] = { 0, 1, 1, 1 };
    int nb = 1;
    const double a = 3 * q[3], b = 2 * q[2], cc = q[1];
    const double scale = fabs(a) + fabs(b) + fabs(cc);
    if (fabs(a) > 1e-14 * scale) {
        const double disc = b * b - 4 * a * cc;
        if (disc >= 0) {
            const double s = sqrt(disc);
            const double qq = -0.5 * (b + (b >= 0 ? s : -s));
            const double r1 = qq / a, r2 = qq != 0 ? cc / qq : r1;
            const double lo = r2 < r1 ? r2 : r1, hi = r1 < r2 ? r2 : r1; // std::min, std::max
            if (lo > 0 && lo < 1)
                breaks[nb++] = lo;
            if (hi > 0 && hi < 1)
                breaks[nb++] = hi;
        }
    } else if (fabs(b) > 1e-14 * scale) {
        const double r = -cc / b;
        if (r > 0 && r < 1)
            breaks[nb++] = r;
    }
    // breaks[1..nb) is already increasing (lo before hi).
    breaks[nb++] = 1.0;
    for (int k = 1; k < nb; ++k) {
        double lo = breaks[k - 1], hi = breaks[k];
        if (eval_cubic(q, hi) > 0)
            continue;
        for (int it = 0; it < 80 && hi - lo > 1e-15; ++it) {
            const double mid = 0.5 * (lo + hi);
            if (eval_cubic(q, mid) > 0)
                lo = mid;
            else
                hi = mid;
        }
        return lo;
    }
    return 1.0;
}

/// @brief Largest t in (0, 1] such that the element keeps more than `keep` times its volume at x along
/// x + s p for all s in [0, t]: 0 if its volume at x is not positive, 1 if it never decreases
/// (the mesh's bound is the minimum over its elements).
template <int dim> DIFFIPC_HD inline double element_step_bound(const double* xe, const double* pe, double keep)
{
    double c[4];
    volume_polynomial<dim>(xe, pe, c);
    if (c[0] <= 0)
        return 0.0;
    if (c[1] >= 0 && c[2] >= 0 && c[3] >= 0)
        return 1.0;
    return first_crossing(c, keep * c[0]);
}

} // namespace diffipc::kernels
