#pragma once
/// @file small_matrix.hpp
/// Fixed-size dense helpers on raw row-major arrays, callable on the host and the device
/// (no Eigen: this header is compiled by nvcc for the GPU and by the host compiler for the CPU).
/// A dim by dim matrix M is stored as M[i * dim + j]; dim is 2 or 3.
/// The formulas are those Eigen uses for fixed 2x2 and 3x3 matrices, so that the GPU path
/// rounds like the CPU path as far as possible.

#include "forward/kernels/host_device.hpp"

namespace diffipc::kernels {

/// @brief det M of a dim by dim row-major matrix (Eigen's expansion along the first column).
template <int dim, class T> DIFFIPC_HD inline T determinant(const T* M)
{
    if constexpr (dim == 2) {
        return M[0] * M[3] - M[2] * M[1];
    } else {
        // Eigen's bruteforce_det3_helper(m, a, b, c) = m(0,a) (m(1,b) m(2,c) - m(1,c) m(2,b)),
        // det = h(0,1,2) - h(1,0,2) + h(2,0,1).
        return M[0] * (M[4] * M[8] - M[5] * M[7]) - M[1] * (M[3] * M[8] - M[5] * M[6])
            + M[2] * (M[3] * M[7] - M[4] * M[6]);
    }
}

/// @brief Cofactor matrix cof(M) = det(M) M^{-T} (dim by dim, row-major out).
/// 2D: [[M11, -M10], [-M01, M00]]; 3D: columns cof_{:,0} = M_{:,1} x M_{:,2} and cyclic.
template <int dim, class T> DIFFIPC_HD inline void cofactor(const T* M, T* C)
{
    if constexpr (dim == 2) {
        C[0] = M[3];
        C[1] = -M[2];
        C[2] = -M[1];
        C[3] = M[0];
    } else {
        for (int c = 0; c < 3; ++c) {
            const int p = (c + 1) % 3, q = (c + 2) % 3;
            // column c = (column p) x (column q)
            C[0 * 3 + c] = M[1 * 3 + p] * M[2 * 3 + q] - M[2 * 3 + p] * M[1 * 3 + q];
            C[1 * 3 + c] = M[2 * 3 + p] * M[0 * 3 + q] - M[0 * 3 + p] * M[2 * 3 + q];
            C[2 * 3 + c] = M[0 * 3 + p] * M[1 * 3 + q] - M[1 * 3 + p] * M[0 * 3 + q];
        }
    }
}

/// @brief M^{-1} (dim by dim, row-major out) as cof(M)^T / det M; returns det M (the inverse is
/// not finite where it is 0).
template <int dim, class T> DIFFIPC_HD inline T inverse(const T* M, T* Minv)
{
    T C[dim * dim];
    cofactor<dim>(M, C);
    const T det = determinant<dim>(M);
    const T inv = 1.0 / det;
    for (int i = 0; i < dim; ++i)
        for (int j = 0; j < dim; ++j)
            Minv[i * dim + j] = C[j * dim + i] * inv;
    return det;
}

} // namespace diffipc::kernels
