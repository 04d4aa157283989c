#pragma once
/// @file material.hpp
/// Hyperelastic energy densities Psi(F; mu, lambda), first Piola-Kirchhoff stress P = dPsi/dF and
/// its derivative dP/dF, written once for the CPU path (forward/materials/material.cpp wraps
/// them for Eigen) and the GPU path (cuda/elastic/). 2D is plane strain (the same formulas with
/// d = 2). References: docs/math.md "Materials"; stable neo-Hookean after Smith, de Goes and Kim
/// 2018, in the rest-stable form of Kim and Eberle's course notes.
///
/// Layouts: F and P are dim by dim row-major, F[i * dim + j]; dP/dF is dim^2 by dim^2 row-major
/// with row index(i, j) = i * dim + j and column index(k, l), i.e.
/// A[(i * dim + j) * dim * dim + k * dim + l] = dP_ij / dF_kl.
///
/// Every law here is linear in (mu, lambda) for a fixed F: forward/potentials/elastic_potential.cpp
/// takes dP/dmu and dP/dlambda as the stress at (mu, lambda) = (1, 0) and (0, 1). A law that is
/// not linear in them must change that too.
///
/// Adding a law: its enumerator and name (material_model.hpp), a case in the three functions
/// below, its closed-form eigensystem for the GPU's PSD projection (eigensystem.hpp;
/// optional: without one, project_psd's numerical eigensystem is used)
/// and tests/forward/materials/test_material.cpp; docs/scene_format.md lists the names.

#include "forward/kernels/material/material_model.hpp"
#include "forward/kernels/small_matrix.hpp"

namespace diffipc::kernels {

namespace material_detail {

    template <int dim, class T> DIFFIPC_HD inline T squared_norm(const T* M)
    {
        T s = 0;
        for (int k = 0; k < dim * dim; ++k)
            s += M[k] * M[k];
        return s;
    }

    /// E = (F^T F - I) / 2 (StVK's Green strain), row-major.
    template <int dim, class T> DIFFIPC_HD inline void green_strain(const T* F, T* E)
    {
        for (int i = 0; i < dim; ++i)
            for (int j = 0; j < dim; ++j) {
                T s = 0;
                for (int m = 0; m < dim; ++m)
                    s += F[m * dim + i] * F[m * dim + j];
                E[i * dim + j] = 0.5 * (s - (i == j ? 1.0 : 0.0));
            }
    }

    /// Levi-Civita symbol for indices in {0, 1, 2}.
    DIFFIPC_HD inline double levi_civita(int a, int b, int c) { return double((a - b) * (b - c) * (c - a)) / 2.0; }

} // namespace material_detail

/// @brief Energy density Psi(F) (J/m^3); +inf for the neo-Hookean model where J = det F <= 0.
/// @param F dim by dim row-major deformation gradient
/// @param mu, lambda Lame parameters (Pa)
template <int dim, class T>
DIFFIPC_HD inline T energy_density(MaterialModel model, const T* F, non_deduced<T> mu, non_deduced<T> lambda)
{
    switch (model) {
    case MaterialModel::LINEAR: {
        // Psi = mu eps:eps + lambda/2 tr(eps)^2, eps = sym(F) - I
        T sq = 0, tr = 0;
        for (int i = 0; i < dim; ++i)
            for (int j = 0; j < dim; ++j) {
                const T eps = 0.5 * (F[i * dim + j] + F[j * dim + i]) - (i == j ? 1.0 : 0.0);
                sq += eps * eps;
                if (i == j)
                    tr += eps;
            }
        return mu * sq + 0.5 * lambda * tr * tr;
    }
    case MaterialModel::STVK: {
        T E[dim * dim];
        material_detail::green_strain<dim>(F, E);
        T tr = 0;
        for (int i = 0; i < dim; ++i)
            tr += E[i * dim + i];
        return mu * material_detail::squared_norm<dim>(E) + 0.5 * lambda * tr * tr;
    }
    case MaterialModel::NEO_HOOKEAN: {
        const T J = determinant<dim>(F);
        if (!(J > 0))
            return infinity<T>();
        const T lnJ = log(J);
        return 0.5 * mu * (material_detail::squared_norm<dim>(F) - dim) - mu * lnJ + 0.5 * lambda * lnJ * lnJ;
    }
    case MaterialModel::STABLE_NEO_HOOKEAN: {
        const T J = determinant<dim>(F), lp = lambda + mu;
        return 0.5 * mu * (material_detail::squared_norm<dim>(F) - dim) - mu * (J - 1) + 0.5 * lp * (J - 1) * (J - 1);
    }
    }
    return T(NAN);
}

/// @brief First Piola-Kirchhoff stress P = dPsi/dF (Pa), dim by dim row-major. Not finite for
/// the neo-Hookean model where J <= 0 (as on the CPU).
template <int dim, class T>
DIFFIPC_HD inline void stress(MaterialModel model, const T* F, non_deduced<T> mu, non_deduced<T> lambda, T* P)
{
    switch (model) {
    case MaterialModel::LINEAR: {
        // P = 2 mu eps + lambda tr(eps) I
        T tr = 0;
        for (int i = 0; i < dim; ++i)
            tr += F[i * dim + i] - 1.0;
        for (int i = 0; i < dim; ++i)
            for (int j = 0; j < dim; ++j) {
                const T eps = 0.5 * (F[i * dim + j] + F[j * dim + i]) - (i == j ? 1.0 : 0.0);
                P[i * dim + j] = 2.0 * mu * eps + (i == j ? lambda * tr : 0.0);
            }
        return;
    }
    case MaterialModel::STVK: {
        // P = F S, S = 2 mu E + lambda tr(E) I
        T S[dim * dim];
        material_detail::green_strain<dim>(F, S);
        T tr = 0;
        for (int i = 0; i < dim; ++i)
            tr += S[i * dim + i];
        for (int i = 0; i < dim; ++i)
            for (int j = 0; j < dim; ++j)
                S[i * dim + j] = 2.0 * mu * S[i * dim + j] + (i == j ? lambda * tr : 0.0);
        for (int i = 0; i < dim; ++i)
            for (int j = 0; j < dim; ++j) {
                T s = 0;
                for (int m = 0; m < dim; ++m)
                    s += F[i * dim + m] * S[m * dim + j];
                P[i * dim + j] = s;
            }
        return;
    }
    case MaterialModel::NEO_HOOKEAN: {
        // P = mu (F - F^{-T}) + lambda ln J F^{-T},  F^{-T} = cof(F) / J
        T G[dim * dim];
        cofactor<dim>(F, G);
        const T J = determinant<dim>(F), lnJ = log(J);
        for (int k = 0; k < dim * dim; ++k) {
            G[k] /= J;
            P[k] = mu * (F[k] - G[k]) + lambda * lnJ * G[k];
        }
        return;
    }
    case MaterialModel::STABLE_NEO_HOOKEAN: {
        // P = mu F + (lambda' (J - 1) - mu) cof(F),  lambda' = lambda + mu
        T C[dim * dim];
        cofactor<dim>(F, C);
        const T J = determinant<dim>(F), lp = lambda + mu;
        for (int k = 0; k < dim * dim; ++k)
            P[k] = mu * F[k] + (lp * (J - 1) - mu) * C[k];
        return;
    }
    }
}

/// @brief dP/dF (dim^2 by dim^2, row-major, layout in the file comment). Not finite for the
/// neo-Hookean model where J <= 0.
template <int dim, class T>
DIFFIPC_HD inline void stress_derivative(
    MaterialModel model, const T* F, non_deduced<T> mu, non_deduced<T> lambda, T* A)
{
    constexpr int n = dim * dim;
    switch (model) {
    case MaterialModel::LINEAR: {
        for (int k = 0; k < n * n; ++k)
            A[k] = 0;
        for (int i = 0; i < dim; ++i)
            for (int j = 0; j < dim; ++j) {
                A[(i * dim + j) * n + i * dim + j] += mu;
                A[(i * dim + j) * n + j * dim + i] += mu;
                if (i == j)
                    for (int k = 0; k < dim; ++k)
                        A[(i * dim + i) * n + k * dim + k] += lambda;
            }
        return;
    }
    case MaterialModel::STVK: {
        // dP_ij/dF_kl = d_ik S_lj + mu F_il F_kj + mu (F F^T)_ik d_jl + lambda F_ij F_kl
        T S[n], FFt[n];
        material_detail::green_strain<dim>(F, S);
        T tr = 0;
        for (int i = 0; i < dim; ++i)
            tr += S[i * dim + i];
        for (int i = 0; i < dim; ++i)
            for (int j = 0; j < dim; ++j) {
                S[i * dim + j] = 2.0 * mu * S[i * dim + j] + (i == j ? lambda * tr : 0.0);
                T s = 0;
                for (int m = 0; m < dim; ++m)
                    s += F[i * dim + m] * F[j * dim + m];
                FFt[i * dim + j] = s;
            }
        for (int i = 0; i < dim; ++i)
            for (int j = 0; j < dim; ++j)
                for (int k = 0; k < dim; ++k)
                    for (int l = 0; l < dim; ++l)
                        A[(i * dim + j) * n + k * dim + l] = (i == k ? S[l * dim + j] : 0.0)
                            + mu * F[i * dim + l] * F[k * dim + j] + (j == l ? mu * FFt[i * dim + k] : 0.0)
                            + lambda * F[i * dim + j] * F[k * dim + l];
        return;
    }
    case MaterialModel::NEO_HOOKEAN: {
        // dP_ij/dF_kl = mu d_ik d_jl + (mu - lambda ln J) G_il G_kj + lambda G_ij G_kl,  G = F^{-T}
        T G[n];
        cofactor<dim>(F, G);
        const T J = determinant<dim>(F), lnJ = log(J);
        for (int k = 0; k < n; ++k)
            G[k] /= J;
        for (int i = 0; i < dim; ++i)
            for (int j = 0; j < dim; ++j)
                for (int k = 0; k < dim; ++k)
                    for (int l = 0; l < dim; ++l)
                        A[(i * dim + j) * n + k * dim + l] = (i == k && j == l ? mu : 0.0)
                            + (mu - lambda * lnJ) * G[i * dim + l] * G[k * dim + j]
                            + lambda * G[i * dim + j] * G[k * dim + l];
        return;
    }
    case MaterialModel::STABLE_NEO_HOOKEAN: {
        // mu I + lambda' c c^T + (lambda' (J - 1) - mu) d cof(F)/dF,  c = vec cof(F)
        T C[n];
        cofactor<dim>(F, C);
        const T J = determinant<dim>(F), lp = lambda + mu, s = lp * (J - 1) - mu;
        for (int r = 0; r < n; ++r)
            for (int c = 0; c < n; ++c)
                A[r * n + c] = (r == c ? mu : 0.0) + lp * C[r] * C[c];
        if constexpr (dim == 2) {
            // cof = [[F11, -F10], [-F01, F00]]
            A[0 * n + 3] += s;
            A[1 * n + 2] -= s;
            A[2 * n + 1] -= s;
            A[3 * n + 0] += s;
        } else {
            // d cof_ij / dF_kl = sum_mn eps_ikm eps_jln F_mn
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    for (int k = 0; k < 3; ++k)
                        for (int l = 0; l < 3; ++l) {
                            if (i == k || j == l)
                                continue;
                            const int m = 3 - i - k, q = 3 - j - l;
                            const T d = material_detail::levi_civita(i, k, m) * material_detail::levi_civita(j, l, q)
                                * F[m * 3 + q];
                            A[(i * 3 + j) * n + k * 3 + l] += s * d;
                        }
        }
        return;
    }
    }
}

} // namespace diffipc::kernels
