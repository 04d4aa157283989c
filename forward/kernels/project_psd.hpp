#pragma once
/// @file project_psd.hpp
/// Projection of a small symmetric matrix onto the positive semi-definite cone, as the Eigen-based
/// project_psd (forward/materials/material.cpp) does it: a matrix that admits a Cholesky
/// factorization is returned unchanged; otherwise its negative eigenvalues are set to zero,
/// A <- V max(D, 0) V^T. Like Eigen's LLT and SelfAdjointEigenSolver, only the lower
/// triangle of the input is read. The eigensystem comes from a cyclic Jacobi iteration
/// (Golub and Van Loan, "Matrix Computations", 4th ed., Algorithm 8.5.3), which works on
/// the host and the device for any symmetric matrix. The elastic dP/dF uses the closed-form
/// eigensystems of material/eigensystem.hpp instead (the same projection, far fewer operations);
/// the contact barrier's pair Hessians use this one.
///
/// Layout: an n by n matrix is row-major, A[r * n + c].

#include "forward/kernels/host_device.hpp"

namespace diffipc::kernels {

/// @brief True if the lower triangle of A admits a Cholesky factorization, decided as Eigen's
/// unblocked LLT decides it (a pivot <= 0, or NaN, fails).
template <int n> DIFFIPC_HD inline bool cholesky_succeeds(const double* A)
{
    double L[n * n];
    for (int k = 0; k < n * n; ++k)
        L[k] = A[k];
    for (int k = 0; k < n; ++k) {
        double x = L[k * n + k];
        for (int j = 0; j < k; ++j)
            x -= L[k * n + j] * L[k * n + j];
        if (!(x > 0))
            return false;
        x = sqrt(x);
        L[k * n + k] = x;
        for (int r = k + 1; r < n; ++r) {
            double s = L[r * n + k];
            for (int j = 0; j < k; ++j)
                s -= L[r * n + j] * L[k * n + j];
            L[r * n + k] = s / x;
        }
    }
    return true;
}

/// @brief Eigen-decomposition S = V diag(d) V^T of the symmetric matrix whose lower triangle is
/// A, by cyclic Jacobi rotations until every off-diagonal entry is zero (entries below
/// 1e-20 ||S||_F are set to zero) or 64 sweeps.
/// @param A  n by n (lower triangle read)
/// @param d  n eigenvalues (unordered)
/// @param V  n by n, column k the eigenvector of d[k]
template <int n> DIFFIPC_HD inline void symmetric_eigen(const double* A, double* d, double* V)
{
    double S[n * n];
    double frob = 0;
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c) {
            const double v = r >= c ? A[r * n + c] : A[c * n + r];
            S[r * n + c] = v;
            V[r * n + c] = r == c ? 1.0 : 0.0;
            frob += v * v;
        }
    const double negligible = 1e-20 * sqrt(frob);
    for (int sweep = 0; sweep < 64; ++sweep) {
        bool rotated = false;
        for (int p = 0; p < n - 1; ++p)
            for (int q = p + 1; q < n; ++q) {
                const double apq = S[p * n + q];
                if (apq == 0)
                    continue;
                if (!(fabs(apq) > negligible)) {
                    S[p * n + q] = S[q * n + p] = 0;
                    continue;
                }
                rotated = true;
                // The rotation that zeroes S_pq (Golub and Van Loan, Algorithm 8.5.1), in the
                // numerically stable update form with tau = s / (1 + c).
                const double theta = 0.5 * (S[q * n + q] - S[p * n + p]) / apq;
                double t = 1.0 / (fabs(theta) + sqrt(1.0 + theta * theta));
                if (theta < 0)
                    t = -t;
                const double c = 1.0 / sqrt(1.0 + t * t), s = t * c, tau = s / (1.0 + c);
                S[p * n + p] -= t * apq;
                S[q * n + q] += t * apq;
                S[p * n + q] = S[q * n + p] = 0;
                for (int r = 0; r < n; ++r) {
                    if (r == p || r == q)
                        continue;
                    const double g = S[r * n + p], h = S[r * n + q];
                    S[r * n + p] = S[p * n + r] = g - s * (h + g * tau);
                    S[r * n + q] = S[q * n + r] = h + s * (g - h * tau);
                }
                for (int r = 0; r < n; ++r) {
                    const double g = V[r * n + p], h = V[r * n + q];
                    V[r * n + p] = g - s * (h + g * tau);
                    V[r * n + q] = h + s * (g - h * tau);
                }
            }
        if (!rotated)
            break;
    }
    for (int k = 0; k < n; ++k)
        d[k] = S[k * n + k];
}

/// @brief In place: A <- A if its lower triangle admits a Cholesky factorization, else
/// V max(D, 0) V^T (the closest positive semi-definite matrix in the Frobenius norm).
/// @param A n by n symmetric, row-major
/// @return true if A was changed (the eigen-decomposition was needed)
template <int n> DIFFIPC_HD inline bool project_psd(double* A)
{
    if (cholesky_succeeds<n>(A))
        return false;
    double d[n], V[n * n];
    symmetric_eigen<n>(A, d, V);
    for (int k = 0; k < n; ++k)
        d[k] = d[k] > 0 ? d[k] : 0.0;
    for (int r = 0; r < n; ++r)
        for (int c = 0; c < n; ++c) {
            double s = 0;
            for (int k = 0; k < n; ++k)
                s += V[r * n + k] * d[k] * V[c * n + k];
            A[r * n + c] = s;
        }
    return true;
}

} // namespace diffipc::kernels
