#pragma once
/// @file friction_pair.hpp
/// The lagged friction of one contact pair on the host and the device: its value, gradient and
/// Hessian, written once for FrictionPotential (forward/contact/friction/friction_potential.cpp)
/// and the GPU's DeviceFriction (cuda/contact/device_friction.cu). Per pair,
/// with the data lagged at the start of the step (FrictionContact: the closest-point weights gamma,
/// the tangent basis T, the coefficient mu and the normal force lambda):
///   u = T^T sum_i gamma_i (x_i - x0_i)   (2D: one tangent, u_1 = 0),   y = |u|,
///   D = mu lambda f0(y, eps),   eps = eps_v h,
///   f0(y) = -y^3 / (3 eps^2) + y^2 / eps + eps / 3 for y < eps, y beyond (IPC's mollified speed),
///   dD/dx_i = gamma_i mu lambda (f1(y) / y) T u,   f1 = f0',
///   d2D/dx_i dx_j = gamma_i gamma_j mu lambda T M T^T,
///   M = (f1 / y) I + (d(f1 / y) / dy) u u^T / y  (PSD for every y; (2 / eps) I at y = 0).
/// Layouts: the pair's local dofs are vertex-major, dim per vertex (n = #vertices * dim); the Hessian
/// is n by n, row-major.

#include "forward/kernels/vec3.hpp"

namespace diffipc::kernels {

/// One lagged friction pair (FrictionContact's fields the evaluation needs), in doubles: the lagged
/// data are constants of a step.
struct FrictionPair {
    int num_vertices = 0; ///< 2 (vertex-plane), 3 (vertex-edge) or 4
    double weights[4] = { 0, 0, 0, 0 }; ///< gamma: p - q = sum_i gamma_i x_i at the lagged state
    double tangent[6] = { 0, 0, 0, 0, 0, 0 }; ///< T's columns t0 (3), t1 (3; zero in 2D)
    double scale = 0; ///< mu lambda (N)
};

/// IPC's mollified speed f0, its derivative f1 and f1'.
template <class T> DIFFIPC_HD inline T friction_f0(T y, T eps)
{
    if (y >= eps)
        return y;
    return -y * y * y / (3 * eps * eps) + y * y / eps + eps / 3;
}

template <class T> DIFFIPC_HD inline T friction_f1(T y, T eps)
{
    if (y >= eps)
        return 1;
    return -y * y / (eps * eps) + 2 * y / eps;
}

template <class T> DIFFIPC_HD inline T friction_f1_derivative(T y, T eps)
{
    if (y >= eps)
        return 0;
    return -2 * y / (eps * eps) + 2 / eps;
}

/// @brief The pair's friction energy mu lambda f0(|u|, eps) and, where the pointers are given, its
/// gradient (n) and Hessian (n by n, row-major) in the pair's local dofs (file comment).
/// @param dim  2 or 3
/// @param dx   the pair's vertices' displacements since the step's start, x_i - x0_i (z = 0 in 2D)
/// @param eps  eps_v h (> 0)
template <class T>
DIFFIPC_HD inline T pair_friction(
    int dim, const FrictionPair& f, const Vec3<T>* dx, non_deduced<T> eps, non_deduced<T>* grad, non_deduced<T>* hess)
{
    const int nv = f.num_vertices, n = nv * dim;
    // The relative tangential displacement u = T^T r, r = sum_i gamma_i dx_i.
    Vec3<T> r(0, 0, 0);
    for (int i = 0; i < nv; ++i)
        r = r + f.weights[i] * dx[i];
    const Vec3<T> t0(f.tangent[0], f.tangent[1], f.tangent[2]), t1(f.tangent[3], f.tangent[4], f.tangent[5]);
    T u[2] = { dot(t0, r), dim == 3 ? dot(t1, r) : 0.0 };
    const T y = sqrt(u[0] * u[0] + u[1] * u[1]);
    const T energy = f.scale * friction_f0(y, eps);
    if (grad) {
        // f1(y) / y stays finite as y -> 0 (2 / eps); at y = 0 the gradient is zero anyway.
        const T ratio = y > 0 ? friction_f1(y, eps) / y : 0.0;
        const Vec3<T> force = (f.scale * ratio) * (u[0] * t0 + u[1] * t1);
        for (int i = 0; i < nv; ++i)
            for (int d = 0; d < dim; ++d)
                grad[i * dim + d] = f.weights[i] * (d == 0 ? force.x : d == 1 ? force.y : force.z);
    }
    if (hess) {
        // M = (f1/y) I + (d(f1/y)/dy) u u^T / y: for y < eps, 2/eps - y/eps^2 and -1/(eps^2 y); for
        // y >= eps, 1/y and -1/y^3.
        T M[2][2];
        if (y < eps) {
            const T a = 2 / eps - y / (eps * eps);
            for (int p = 0; p < 2; ++p)
                for (int q = 0; q < 2; ++q)
                    M[p][q] = (p == q ? a : 0.0) - (y > 0 ? u[p] * u[q] / (eps * eps * y) : 0.0);
        } else {
            for (int p = 0; p < 2; ++p)
                for (int q = 0; q < 2; ++q)
                    M[p][q] = (p == q ? 1 / y : 0.0) - u[p] * u[q] / (y * y * y);
        }
        if (dim == 2)
            M[0][1] = M[1][0] = M[1][1] = 0;
        // K = mu lambda T M T^T (dim by dim), then the blocks gamma_i gamma_j K.
        const T Tb[3][2] = { { t0.x, t1.x }, { t0.y, t1.y }, { t0.z, t1.z } };
        T K[3][3];
        for (int a = 0; a < dim; ++a)
            for (int b = 0; b < dim; ++b) {
                T s = 0;
                for (int p = 0; p < 2; ++p)
                    for (int q = 0; q < 2; ++q)
                        s += Tb[a][p] * M[p][q] * Tb[b][q];
                K[a][b] = f.scale * s;
            }
        for (int i = 0; i < nv; ++i)
            for (int j = 0; j < nv; ++j)
                for (int a = 0; a < dim; ++a)
                    for (int b = 0; b < dim; ++b)
                        hess[(i * dim + a) * n + j * dim + b] = f.weights[i] * f.weights[j] * K[a][b];
    }
    return energy;
}

} // namespace diffipc::kernels
