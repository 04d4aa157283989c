#pragma once
/// @file eigensystem.hpp
/// Closed-form eigensystems of dP/dF for the four material models of forward/kernels/material/material.hpp, and the
/// positive semi-definite projection of dP/dF built from them (host and device).
///
/// The isotropic models (StVK, neo-Hookean, stable neo-Hookean) are functions Psi(s) of the
/// signed singular values of F = U diag(s) V^T (U, V rotations; only the last s may be negative).
/// With psi_i = dPsi/ds_i, the dim^2 eigenpairs of d^2 Psi / dF^2 are (Smith, de Goes and Kim,
/// "Analytic Eigensystems for Isotropic Distortion Energies", ACM TOG 38(1), 2019):
/// - dim "scaling" modes U diag(z) V^T, (z, h) an eigenpair of the dim by dim d^2 Psi / ds^2;
/// - per pair i < j a "twist" (U (e_i e_j^T - e_j e_i^T) V^T / sqrt 2, eigenvalue
///   (psi_i + psi_j) / (s_i + s_j)) and a "flip" (the same with +, eigenvalue
///   (psi_i - psi_j) / (s_i - s_j)).
/// The pair eigenvalues are written per model in a form without those divisions (derived in
/// docs/math.md, "Closed-form eigensystems"), so that repeated singular values need no special case.
/// Linear elasticity, not a function of the singular values, has the eigenvalues 0
/// (skew-symmetric modes), 2 mu (symmetric traceless) and 2 mu + dim lambda (vec I).
///
/// Layouts as in forward/kernels/material/material.hpp: F, U, V dim by dim row-major (U[a * dim + k] = component a of the
/// k-th singular vector); dP/dF dim^2 by dim^2 row-major, row index i * dim + j for F_ij.

#include "forward/kernels/material/material.hpp"
#include "forward/kernels/project_psd.hpp"
#include "forward/kernels/small_matrix.hpp"

namespace diffipc::kernels {

/// @brief Signed singular value decomposition F = U diag(s) V^T with det U = det V = 1,
/// |s_0| >= |s_1| >= ... and only the last s_i possibly negative (det F < 0).
/// V comes from the eigenvectors of F^T F (cyclic Jacobi on the dim by dim matrix); U's first
/// dim - 1 columns are F v_k orthonormalized (Gram-Schmidt), its last completes a rotation, and
/// s_k = u_k . F v_k. Accurate to round-off relative to |F| for every s, including small ones.
/// @return false where F is of rank < dim - 1 to within 1e-7 |F| (U is not determined), so that
/// callers fall back to a numerical eigensystem.
template <int dim> DIFFIPC_HD inline bool signed_svd(const double* F, double* U, double* s, double* V)
{
    double C[dim * dim], d[dim], W[dim * dim];
    for (int i = 0; i < dim; ++i)
        for (int j = 0; j < dim; ++j) {
            double c = 0;
            for (int m = 0; m < dim; ++m)
                c += F[m * dim + i] * F[m * dim + j];
            C[i * dim + j] = c;
        }
    symmetric_eigen<dim>(C, d, W);
    int order[dim];
    for (int k = 0; k < dim; ++k)
        order[k] = k;
    for (int a = 1; a < dim; ++a) // insertion sort, descending eigenvalues of F^T F
        for (int b = a; b > 0 && d[order[b]] > d[order[b - 1]]; --b) {
            const int t = order[b];
            order[b] = order[b - 1];
            order[b - 1] = t;
        }
    for (int i = 0; i < dim; ++i)
        for (int k = 0; k < dim; ++k)
            V[i * dim + k] = W[i * dim + order[k]];
    if (determinant<dim>(V) < 0)
        for (int i = 0; i < dim; ++i)
            V[i * dim + dim - 1] = -V[i * dim + dim - 1];

    double Fv[dim * dim]; // column k = F v_k
    for (int a = 0; a < dim; ++a)
        for (int k = 0; k < dim; ++k) {
            double t = 0;
            for (int m = 0; m < dim; ++m)
                t += F[a * dim + m] * V[m * dim + k];
            Fv[a * dim + k] = t;
        }
    double n0 = 0;
    for (int a = 0; a < dim; ++a)
        n0 += Fv[a * dim] * Fv[a * dim];
    n0 = sqrt(n0);
    if (!(n0 > 0))
        return false;
    for (int a = 0; a < dim; ++a)
        U[a * dim] = Fv[a * dim] / n0;
    if constexpr (dim == 2) {
        U[1] = -U[2];
        U[3] = U[0];
    } else {
        double p = 0;
        for (int a = 0; a < 3; ++a)
            p += U[a * 3] * Fv[a * 3 + 1];
        double w[3], n1 = 0;
        for (int a = 0; a < 3; ++a) {
            w[a] = Fv[a * 3 + 1] - p * U[a * 3];
            n1 += w[a] * w[a];
        }
        n1 = sqrt(n1);
        if (!(n1 > 1e-7 * n0))
            return false;
        for (int a = 0; a < 3; ++a)
            U[a * 3 + 1] = w[a] / n1;
        U[0 * 3 + 2] = U[1 * 3 + 0] * U[2 * 3 + 1] - U[2 * 3 + 0] * U[1 * 3 + 1];
        U[1 * 3 + 2] = U[2 * 3 + 0] * U[0 * 3 + 1] - U[0 * 3 + 0] * U[2 * 3 + 1];
        U[2 * 3 + 2] = U[0 * 3 + 0] * U[1 * 3 + 1] - U[1 * 3 + 0] * U[0 * 3 + 1];
    }
    for (int k = 0; k < dim; ++k) {
        double t = 0;
        for (int a = 0; a < dim; ++a)
            t += U[a * dim + k] * Fv[a * dim + k];
        s[k] = t;
    }
    return true;
}

/// Number of singular-value pairs i < j: 1 in 2D, 3 in 3D, ordered (0,1), (0,2), (1,2).
template <int dim> constexpr int num_singular_pairs = dim*(dim - 1) / 2;

/// @brief The eigenvalue data of an isotropic model at signed singular values s: the Hessian
/// d^2 Psi / ds^2 (dim by dim, row-major) and per pair i < j the twist and flip eigenvalues.
/// @brief Whether the laws below have their eigensystem here: a law of
/// forward/kernels/material/material.hpp that is not listed is projected with project_psd's
/// numerical eigensystem (slower, the same projection).
DIFFIPC_HD inline bool has_closed_form_eigensystem(MaterialModel model)
{
    return model == MaterialModel::STVK || model == MaterialModel::NEO_HOOKEAN
        || model == MaterialModel::STABLE_NEO_HOOKEAN;
}

/// Not for MaterialModel::LINEAR (not a function of s).
template <int dim>
DIFFIPC_HD inline void singular_value_eigendata(
    MaterialModel model, const double* s, double mu, double lambda, double* Hs, double* twist, double* flip)
{
    // other[i]: the product of the singular values other than s_i (J / s_i without the division).
    double J = 1, other[dim], trE = 0;
    for (int i = 0; i < dim; ++i) {
        J *= s[i];
        trE += 0.5 * (s[i] * s[i] - 1);
        other[i] = 1;
        for (int k = 0; k < dim; ++k)
            if (k != i)
                other[i] *= s[k];
    }
    // The models' scalars, once: StVK's S_i = 2 mu E_i + lambda tr E (E_i = (s_i^2 - 1) / 2); the
    // neo-Hookean's a = lambda ln J - mu (psi_i = mu s_i + a / s_i); the stable neo-Hookean's
    // c = lambda' (J - 1) - mu (psi_i = mu s_i + c other_i).
    const double a = model == MaterialModel::NEO_HOOKEAN ? lambda * log(J) - mu : 0.0;
    const double lp = lambda + mu, c = lp * (J - 1) - mu;
    double S[dim];
    for (int i = 0; i < dim; ++i)
        S[i] = mu * (s[i] * s[i] - 1) + lambda * trE;
    // r(i, j): d other[i] / d s_j for i != j (the third singular value in 3D, 1 in 2D).
    const auto r = [&](int i, int j) { return dim == 3 ? s[3 - i - j] : 1.0; };
    int pair = 0;
    for (int i = 0; i < dim; ++i)
        for (int j = i + 1; j < dim; ++j, ++pair)
            switch (model) {
            case MaterialModel::STVK:
                twist[pair] = 0.5 * (S[i] + S[j]) + 0.5 * mu * (s[i] - s[j]) * (s[i] - s[j]);
                flip[pair] = 0.5 * (S[i] + S[j]) + 0.5 * mu * (s[i] + s[j]) * (s[i] + s[j]);
                break;
            case MaterialModel::NEO_HOOKEAN: {
                const double t = a / (s[i] * s[j]);
                twist[pair] = mu + t;
                flip[pair] = mu - t;
                break;
            }
            case MaterialModel::STABLE_NEO_HOOKEAN:
                twist[pair] = mu + c * r(i, j);
                flip[pair] = mu - c * r(i, j);
                break;
            default:
                twist[pair] = flip[pair] = NAN;
            }
    for (int i = 0; i < dim; ++i)
        for (int j = 0; j < dim; ++j) {
            double h = NAN;
            switch (model) {
            case MaterialModel::STVK:
                h = i == j ? S[i] + (2 * mu + lambda) * s[i] * s[i] : lambda * s[i] * s[j];
                break;
            case MaterialModel::NEO_HOOKEAN:
                h = i == j ? mu + (lambda - a) / (s[i] * s[i]) : lambda / (s[i] * s[j]);
                break;
            case MaterialModel::STABLE_NEO_HOOKEAN:
                h = i == j ? mu + lp * other[i] * other[i] : lp * other[i] * other[j] + c * r(i, j);
                break;
            default:
                break;
            }
            Hs[i * dim + j] = h;
        }
}

/// @brief A <- sum_k w(lambda_k) q_k q_k^T over the closed-form eigenpairs (lambda_k, q_k) of
/// dP/dF of an isotropic model at F = U diag(s) V^T, with w(l) = max(l, 0) if `clamp`, else l
/// (then A is dP/dF itself: the tests' check of the eigensystem).
template <int dim>
DIFFIPC_HD inline void isotropic_stress_derivative_from_eigensystem(MaterialModel model, const double* U,
    const double* s, const double* V, double mu, double lambda, bool clamp, double* A)
{
    constexpr int n = dim * dim, pairs = num_singular_pairs<dim>;
    double Hs[dim * dim], twist[pairs], flip[pairs], h[dim], Z[dim * dim];
    singular_value_eigendata<dim>(model, s, mu, lambda, Hs, twist, flip);
    symmetric_eigen<dim>(Hs, h, Z);
    for (int k = 0; k < n * n; ++k)
        A[k] = 0;
    const auto add = [&](double l, const double* q) {
        if (clamp && !(l > 0))
            return;
        for (int r = 0; r < n; ++r)
            for (int c = 0; c < n; ++c)
                A[r * n + c] += l * q[r] * q[c];
    };
    double q[n];
    for (int m = 0; m < dim; ++m) { // scaling modes U diag(z_m) V^T
        for (int a = 0; a < dim; ++a)
            for (int b = 0; b < dim; ++b) {
                double t = 0;
                for (int k = 0; k < dim; ++k)
                    t += U[a * dim + k] * Z[k * dim + m] * V[b * dim + k];
                q[a * dim + b] = t;
            }
        add(h[m], q);
    }
    const double root_half = sqrt(0.5);
    int pair = 0;
    for (int i = 0; i < dim; ++i)
        for (int j = i + 1; j < dim; ++j, ++pair)
            for (int sign = -1; sign <= 1; sign += 2) { // twist (-), flip (+)
                for (int a = 0; a < dim; ++a)
                    for (int b = 0; b < dim; ++b)
                        q[a * dim + b]
                            = root_half * (U[a * dim + i] * V[b * dim + j] + sign * U[a * dim + j] * V[b * dim + i]);
                add(sign < 0 ? twist[pair] : flip[pair], q);
            }
}

/// @brief In place: the positive semi-definite projection of A = dP/dF(F) (the matrix that
/// stress_derivative gives for these arguments), as project_psd<dim^2>(A) defines it: A
/// unchanged if it admits a Cholesky factorization, else its negative eigenvalues set to zero,
/// here from the closed-form eigensystem. Falls back to project_psd's numerical eigensystem
/// where signed_svd does not determine U.
/// @return true if A was changed
template <int dim>
DIFFIPC_HD inline bool project_stress_derivative(
    MaterialModel model, const double* F, double mu, double lambda, double* A)
{
    constexpr int n = dim * dim;
    if (cholesky_succeeds<n>(A))
        return false;
    if (model == MaterialModel::LINEAR) {
        // A = 2 mu P_dev + (2 mu + dim lambda) P_vol on the symmetric part, 0 on the skew part,
        // with P_vol = vec(I) vec(I)^T / dim and P_dev = (I + T) / 2 - P_vol.
        const double dev = 2 * mu > 0 ? 2 * mu : 0.0, vol_l = 2 * mu + dim * lambda, vol = vol_l > 0 ? vol_l : 0.0;
        if (dev == 2 * mu && vol == vol_l)
            return false; // positive semi-definite already (singular on the skew part)
        for (int i = 0; i < dim; ++i)
            for (int j = 0; j < dim; ++j)
                for (int k = 0; k < dim; ++k)
                    for (int l = 0; l < dim; ++l) {
                        const double sym = 0.5 * ((i == k && j == l ? 1.0 : 0.0) + (i == l && j == k ? 1.0 : 0.0));
                        const double pv = (i == j && k == l) ? 1.0 / dim : 0.0;
                        A[(i * dim + j) * n + k * dim + l] = dev * (sym - pv) + vol * pv;
                    }
        return true;
    }
    double U[dim * dim], s[dim], V[dim * dim];
    if (!has_closed_form_eigensystem(model) || !signed_svd<dim>(F, U, s, V))
        return project_psd<n>(A);
    isotropic_stress_derivative_from_eigensystem<dim>(model, U, s, V, mu, lambda, true, A);
    return true;
}

} // namespace diffipc::kernels
