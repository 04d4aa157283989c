#include "cuda/contact/pair_gather.hpp"

#include "cuda/common/device.hpp"

#include <cuda_runtime.h>

namespace diffipc::gpu {

namespace {

    constexpr int THREADS = 128;

    int grid(size_t n) { return int((n + THREADS - 1) / THREADS); }

    __global__ void gather_gradient(int num_rows, int dim, int np, const int* __restrict__ rows,
        const int* __restrict__ offsets, const int* __restrict__ codes, const double* __restrict__ local, double scale,
        double* __restrict__ g)
    {
        const int t = blockIdx.x * blockDim.x + threadIdx.x;
        if (t >= num_rows * dim)
            return;
        const int v = rows[t / dim], i = t % dim;
        double acc = g[size_t(v) * dim + i];
        for (int c = offsets[v]; c < offsets[v + 1]; ++c) {
            const int p = codes[c] / 4, a = codes[c] % 4;
            acc += scale * local[size_t(a * dim + i) * np + p];
        }
        g[size_t(v) * dim + i] = acc;
    }

    __global__ void gather_hessian(int slots, int dim, int np, const int* __restrict__ offsets,
        const int* __restrict__ codes, const double* __restrict__ local, double* __restrict__ values)
    {
        const int t = blockIdx.x * blockDim.x + threadIdx.x;
        if (t >= slots * dim * dim)
            return;
        const int s = t / (dim * dim), i = (t / dim) % dim, k = t % dim, L = 4 * dim;
        double acc = values[t];
        for (int c = offsets[s]; c < offsets[s + 1]; ++c) {
            const int code = codes[c];
            const int p = code / 16, a = (code / 4) % 4, b = code % 4;
            acc += local[size_t((a * dim + i) * L + b * dim + k) * np + p];
        }
        values[t] = acc;
    }

} // namespace

void gather_pair_gradients(int num_rows, int dim, int np, const int* rows, const int* offsets, const int* codes,
    const double* local, double scale, double* d_g)
{
    if (num_rows == 0 || np == 0)
        return;
    gather_gradient<<<grid(size_t(num_rows) * size_t(dim)), THREADS>>>(
        num_rows, dim, np, rows, offsets, codes, local, scale, d_g);
    check_cuda(cudaGetLastError(), "launch of a pair gradient gather");
}

void gather_pair_hessians(
    int slots, int dim, int np, const int* offsets, const int* codes, const double* local, double* d_values)
{
    const size_t entries = size_t(slots) * size_t(dim * dim);
    if (entries == 0 || np == 0)
        return;
    gather_hessian<<<grid(entries), THREADS>>>(slots, dim, np, offsets, codes, local, d_values);
    check_cuda(cudaGetLastError(), "launch of a pair Hessian gather");
}

} // namespace diffipc::gpu
