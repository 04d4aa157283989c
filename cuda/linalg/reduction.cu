#include "cuda/linalg/reduction.hpp"

#include "cuda/common/device.hpp"

#include <cuda_runtime.h>

#include <algorithm>

namespace diffipc::gpu {

namespace {

    constexpr int THREADS = 256;
    static_assert(REDUCTION_PARTIALS == THREADS, "the second stage reduces one block's worth of partial sums");

    /// The pairwise halving of one block's THREADS values in shared memory (fixed order).
    template <int N> __device__ void block_tree(double (&s)[N][THREADS])
    {
        for (int h = THREADS / 2; h > 0; h /= 2) {
            __syncthreads();
            if (threadIdx.x < h)
                for (int q = 0; q < N; ++q)
                    s[q][threadIdx.x] += s[q][threadIdx.x + h];
        }
        __syncthreads();
    }

    /// Terms of the reductions: a plain sum, a dot product, two dot products.
    struct SumTerm {
        const double* v;
        __device__ void operator()(size_t k, double* out) const { out[0] += v[k]; }
    };
    struct DotTerm {
        const double *a, *b;
        __device__ void operator()(size_t k, double* out) const { out[0] += a[k] * b[k]; }
    };
    struct Dot2Term {
        const double *a, *b, *c, *d;
        __device__ void operator()(size_t k, double* out) const
        {
            out[0] += a[k] * b[k];
            out[1] += c[k] * d[k];
        }
    };

    /// Stage 1: block b writes its N sums to partials[q * THREADS + b].
    template <int N, typename Term> __global__ void partial_sums(Term term, size_t n, double* partials)
    {
        __shared__ double s[N][THREADS];
        double acc[N];
        for (int q = 0; q < N; ++q)
            acc[q] = 0;
        const size_t stride = size_t(gridDim.x) * THREADS;
        for (size_t k = size_t(blockIdx.x) * THREADS + threadIdx.x; k < n; k += stride)
            term(k, acc);
        for (int q = 0; q < N; ++q)
            s[q][threadIdx.x] = acc[q];
        block_tree<N>(s);
        if (threadIdx.x == 0)
            for (int q = 0; q < N; ++q)
                partials[q * THREADS + blockIdx.x] = s[q][0];
    }

    /// Stage 2: one block reduces the `blocks` partial sums of each quantity.
    template <int N> __global__ void final_sums(const double* partials, int blocks, double* result)
    {
        __shared__ double s[N][THREADS];
        for (int q = 0; q < N; ++q)
            s[q][threadIdx.x] = int(threadIdx.x) < blocks ? partials[q * THREADS + threadIdx.x] : 0.0;
        block_tree<N>(s);
        if (threadIdx.x == 0)
            for (int q = 0; q < N; ++q)
                result[q] = s[q][0];
    }

    template <int N, typename Term> void reduce(Term term, size_t n, double* d_partials, double* d_result)
    {
        const int blocks = int(std::max<size_t>(1, std::min<size_t>((n + THREADS - 1) / THREADS, THREADS)));
        partial_sums<N><<<blocks, THREADS>>>(term, n, d_partials);
        check_cuda(cudaGetLastError(), "launch of a deterministic reduction");
        final_sums<N><<<1, THREADS>>>(d_partials, blocks, d_result);
        check_cuda(cudaGetLastError(), "launch of a deterministic reduction");
    }

} // namespace

void deterministic_sum(const double* d_values, size_t n, double* d_partials, double* d_result)
{
    reduce<1>(SumTerm { d_values }, n, d_partials, d_result);
}

void deterministic_dot(const double* d_a, const double* d_b, size_t n, double* d_partials, double* d_result)
{
    reduce<1>(DotTerm { d_a, d_b }, n, d_partials, d_result);
}

void deterministic_dot2(const double* d_a, const double* d_b, const double* d_c, const double* d_d, size_t n,
    double* d_partials, double* d_result)
{
    reduce<2>(Dot2Term { d_a, d_b, d_c, d_d }, n, d_partials, d_result);
}

} // namespace diffipc::gpu
