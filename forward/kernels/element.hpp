#pragma once
/// @file element.hpp
/// Energy |e| Psi(F), gradient and Hessian of one P1 element (a triangle in 2D plane strain,
/// a tetrahedron in 3D) w.r.t. its deformed vertex positions, callable on the host and the
/// device.
///
/// Layouts (dim = 2 or 3, L = dim (dim + 1) local dofs):
/// - rest, xe: (dim+1) by dim vertex positions, row per vertex, row-major: xe[a * dim + i].
/// - G: (dim+1) by dim shape-function gradients dN_a/dX_j, row-major: G[a * dim + j]
///   (rows 1..dim are Dm^{-1}, row 0 minus their sum; Dm's columns are X_a - X_0).
/// - gradients: L values, vertex-major: g[a * dim + i].
/// - Hessians: L by L row-major, H[(a * dim + i) * L + b * dim + k].
///
/// F, the energy, the gradient and the Hessian are templates over the scalar T (double today; dual
/// numbers give their directional derivatives), the rest data and the `_from_rest` forms are on doubles.

#include "forward/kernels/material/eigensystem.hpp"

namespace diffipc::kernels {

/// @brief Rest data of one element from its rest vertex positions.
/// @param rest   (dim+1) by dim rest positions (m)
/// @param G      out: (dim+1) by dim shape-function gradients (1/m)
/// @param volume out: rest volume (area in 2D) |det Dm| / dim! (m^dim)
/// @return det Dm (0 for a degenerate element, whose G is not finite)
template <int dim> DIFFIPC_HD inline double element_rest_data(const double* rest, double* G, double& volume)
{
    double Dm[dim * dim], Dinv[dim * dim];
    for (int a = 0; a < dim; ++a)
        for (int i = 0; i < dim; ++i)
            Dm[i * dim + a] = rest[(a + 1) * dim + i] - rest[i];
    const double det = inverse<dim>(Dm, Dinv);
    volume = fabs(det) / (dim == 2 ? 2.0 : 6.0);
    for (int j = 0; j < dim; ++j) {
        double sum = 0;
        for (int a = 1; a <= dim; ++a) {
            G[a * dim + j] = Dinv[(a - 1) * dim + j];
            sum += Dinv[(a - 1) * dim + j];
        }
        G[j] = -sum;
    }
    return det;
}

/// @brief F = sum_a x_a G_a^T (dim by dim, row-major).
template <int dim, class T> DIFFIPC_HD inline void deformation_gradient(const T* G, const T* xe, T* F)
{
    for (int i = 0; i < dim; ++i)
        for (int j = 0; j < dim; ++j) {
            T s = 0;
            for (int a = 0; a <= dim; ++a)
                s += xe[a * dim + i] * G[a * dim + j];
            F[i * dim + j] = s;
        }
}

/// @brief volume * Psi(F(xe)) (J); +inf for an inverted neo-Hookean element.
/// @param volume rest volume, or any weight times it
template <int dim, class T>
DIFFIPC_HD inline T element_energy(
    MaterialModel model, const T* G, non_deduced<T> volume, const T* xe, non_deduced<T> mu, non_deduced<T> lambda)
{
    T F[dim * dim];
    deformation_gradient<dim>(G, xe, F);
    return volume * energy_density<dim>(model, F, mu, lambda);
}

/// @brief g_(a,i) = volume * sum_j P_ij G_aj (N), L values vertex-major.
template <int dim, class T>
DIFFIPC_HD inline void element_gradient(
    MaterialModel model, const T* G, non_deduced<T> volume, const T* xe, non_deduced<T> mu, non_deduced<T> lambda, T* g)
{
    T F[dim * dim], P[dim * dim];
    deformation_gradient<dim>(G, xe, F);
    stress<dim>(model, F, mu, lambda, P);
    for (int a = 0; a <= dim; ++a)
        for (int i = 0; i < dim; ++i) {
            T s = 0;
            for (int j = 0; j < dim; ++j)
                s += P[i * dim + j] * G[a * dim + j];
            g[a * dim + i] = volume * s;
        }
}

/// @brief H_(a,i),(b,k) = volume * sum_jl A_(ij),(kl) G_aj G_bl (N/m), A = dP/dF, made positive
/// semi-definite first if `project` (project_stress_derivative: the closed-form eigensystem of
/// the dim^2 by dim^2 A; for T = double only, the projection being a search direction's).
/// @param H out: L by L row-major
template <int dim, class T>
DIFFIPC_HD inline void element_hessian(MaterialModel model, const T* G, non_deduced<T> volume, const T* xe,
    non_deduced<T> mu, non_deduced<T> lambda, bool project, T* H)
{
    constexpr int n = dim * dim, L = dim * (dim + 1);
    T F[n], A[n * n];
    deformation_gradient<dim>(G, xe, F);
    stress_derivative<dim>(model, F, mu, lambda, A);
    if constexpr (is_double<T>)
        if (project)
            project_stress_derivative<dim>(model, F, mu, lambda, A);
    // AG_(ij),(b,k) = sum_l A_(ij),(kl) G_bl, then H_(a,i),(b,k) = volume sum_j G_aj AG_(ij),(b,k).
    for (int b = 0; b <= dim; ++b)
        for (int k = 0; k < dim; ++k) {
            T AG[n];
            for (int r = 0; r < n; ++r) {
                T s = 0;
                for (int l = 0; l < dim; ++l)
                    s += A[r * n + k * dim + l] * G[b * dim + l];
                AG[r] = s;
            }
            for (int a = 0; a <= dim; ++a)
                for (int i = 0; i < dim; ++i) {
                    T s = 0;
                    for (int j = 0; j < dim; ++j)
                        s += G[a * dim + j] * AG[i * dim + j];
                    H[(a * dim + i) * L + b * dim + k] = volume * s;
                }
        }
}

/// @name The same from rest and deformed vertex positions ((dim+1) by dim each, row per vertex),
/// the arguments of the CPU's element_energy / element_gradient / element_hessian.
/// @{
template <int dim>
DIFFIPC_HD inline double element_energy_from_rest(
    MaterialModel model, const double* rest, const double* deformed, double mu, double lambda)
{
    double G[(dim + 1) * dim], volume;
    element_rest_data<dim>(rest, G, volume);
    return element_energy<dim>(model, G, volume, deformed, mu, lambda);
}
template <int dim>
DIFFIPC_HD inline void element_gradient_from_rest(
    MaterialModel model, const double* rest, const double* deformed, double mu, double lambda, double* g)
{
    double G[(dim + 1) * dim], volume;
    element_rest_data<dim>(rest, G, volume);
    element_gradient<dim>(model, G, volume, deformed, mu, lambda, g);
}
template <int dim>
DIFFIPC_HD inline void element_hessian_from_rest(
    MaterialModel model, const double* rest, const double* deformed, double mu, double lambda, bool project, double* H)
{
    double G[(dim + 1) * dim], volume;
    element_rest_data<dim>(rest, G, volume);
    element_hessian<dim>(model, G, volume, deformed, mu, lambda, project, H);
}
/// @}

} // namespace diffipc::kernels
