#pragma once
/// @file block_diagonal.cuh
/// z = D z-blocks: the product of a block-diagonal matrix (b x b blocks, row-major, one per block row)
/// with a vector, one thread per scalar row. The block-Jacobi preconditioner (device_pcg.cu) and the
/// multigrid's smoother and power iteration (device_amg.cu) apply their inverted diagonal blocks with it.

namespace diffipc::gpu {

/// z[r b + i] = sum_j blocks[r b^2 + i b + j] y[r b + j] for the n = #block rows * b scalar rows.
template <int B>
__global__ void apply_block_diagonal(
    int n, const double* __restrict__ blocks, const double* __restrict__ y, double* __restrict__ z)
{
    const int row = blockIdx.x * blockDim.x + threadIdx.x;
    if (row >= n)
        return;
    const int r = row / B, i = row % B;
    const double* m = blocks + size_t(r) * (B * B) + i * B;
    double acc = 0;
    for (int j = 0; j < B; ++j)
        acc += m[j] * y[r * B + j];
    z[row] = acc;
}

} // namespace diffipc::gpu
