#include "cuda/periodic/reduced_operator.hpp"

#include "cuda/common/device.hpp"

#include <stdexcept>
#include <string>

namespace diffipc::gpu {

namespace {

    constexpr int THREADS = 256;

    int grid(size_t n) { return int((n + THREADS - 1) / THREADS); }

    /// y = x with the fixed entries zeroed (fixed may be null).
    __global__ void masked_copy_kernel(
        size_t n, const double* __restrict__ x, const unsigned char* __restrict__ fixed, double* __restrict__ y)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k < n)
            y[k] = fixed && fixed[k] ? 0.0 : x[k];
    }

    __global__ void zero_fixed_kernel(size_t n, const unsigned char* __restrict__ fixed, double* __restrict__ y)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k < n && fixed[k])
            y[k] = 0.0;
    }

    /// Block c of out (dim^2 values) = the sum of the class's vertices' diagonal blocks, in vertex order.
    __global__ void class_blocks_kernel(PeriodicView m, const double* __restrict__ full, double* __restrict__ out)
    {
        const int b2 = m.dim * m.dim;
        const int k = blockIdx.x * blockDim.x + threadIdx.x;
        if (k >= m.num_classes * b2)
            return;
        const int c = k / b2, e = k % b2;
        double s = 0;
        for (int r = m.class_start[c]; r < m.class_start[c + 1]; ++r)
            s += full[m.class_vertices[r] * b2 + e];
        out[k] = s;
    }

    /// out = e_index (n values).
    __global__ void unit_vector_kernel(size_t n, size_t index, double* __restrict__ out)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k < n)
            out[k] = k == index ? 1.0 : 0.0;
    }

    /// Column k of macro block i: out[(C + i) dim^2 + j dim + k] = y[macro_dof(i, j)], j = 0 .. dim - 1.
    __global__ void macro_column_kernel(
        PeriodicView m, int i, int k, const double* __restrict__ y, double* __restrict__ out)
    {
        const int j = threadIdx.x;
        if (j < m.dim)
            out[(m.num_classes + i) * m.dim * m.dim + j * m.dim + k] = y[macro_dof(m, i, j)];
    }

    __global__ void add_kernel(size_t n, const double* __restrict__ x, double* __restrict__ y)
    {
        const size_t k = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (k < n)
            y[k] += x[k];
    }

} // namespace

void OperatorSum::bind(const DeviceLinearOperator& A, const DeviceLinearOperator& B)
{
    if (A.block_size() != B.block_size() || A.num_block_rows() != B.num_block_rows())
        throw std::invalid_argument("OperatorSum::bind: the operators' shapes differ ("
            + std::to_string(A.num_block_rows()) + " and " + std::to_string(B.num_block_rows()) + " block rows)");
    m_A = &A;
    m_B = &B;
    m_y.resize(size_t(A.size()));
    m_blocks.resize(size_t(A.num_block_rows()) * size_t(A.block_size() * A.block_size()));
}

void OperatorSum::multiply(const double* d_x, double* d_y, const unsigned char* d_fixed) const
{
    if (!m_A)
        throw std::logic_error("OperatorSum::multiply: not bound");
    m_A->multiply(d_x, d_y, d_fixed);
    m_B->multiply(d_x, m_y.data(), d_fixed);
    add_kernel<<<grid(m_y.size()), THREADS>>>(m_y.size(), m_y.data(), d_y);
    check_cuda(cudaGetLastError(), "launch of an operator sum's product");
}

void OperatorSum::diagonal_blocks(double* d_out) const
{
    if (!m_A)
        throw std::logic_error("OperatorSum::diagonal_blocks: not bound");
    m_A->diagonal_blocks(d_out);
    m_B->diagonal_blocks(m_blocks.data());
    add_kernel<<<grid(m_blocks.size()), THREADS>>>(m_blocks.size(), m_blocks.data(), d_out);
    check_cuda(cudaGetLastError(), "launch of an operator sum's blocks");
    check_cuda(cudaDeviceSynchronize(), "an operator sum's diagonal blocks");
}

void ReducedOperator::bind(const DeviceLinearOperator& A, DevicePeriodicMap& map)
{
    if (A.block_size() != map.dim() || A.num_block_rows() != map.num_vertices())
        throw std::invalid_argument("ReducedOperator::bind: the operator has " + std::to_string(A.num_block_rows())
            + " block rows of " + std::to_string(A.block_size()) + ", the periodic map "
            + std::to_string(map.num_vertices()) + " vertices in " + std::to_string(map.dim()) + "D");
    m_A = &A;
    m_map = &map;
    const size_t nq = size_t(map.num_reduced()), nx = size_t(A.size());
    m_q.resize(nq);
    m_x.resize(nx);
    m_y.resize(nx);
    m_unit.resize(nq);
    m_column.resize(nq);
    m_full_diagonal.resize(size_t(map.num_vertices()) * size_t(map.dim() * map.dim()));
}

void ReducedOperator::multiply(const double* d_x, double* d_y, const unsigned char* d_fixed) const
{
    if (!m_A)
        throw std::logic_error("ReducedOperator::multiply: not bound");
    const size_t nq = m_q.size();
    const double* x = d_x;
    if (d_fixed) {
        masked_copy_kernel<<<grid(nq), THREADS>>>(nq, d_x, d_fixed, m_q.data());
        check_cuda(cudaGetLastError(), "launch of the reduced product's masked copy");
        x = m_q.data();
    }
    m_map->expand(x, m_x.data(), false);
    m_A->multiply(m_x.data(), m_y.data(), nullptr);
    m_map->reduce(m_y.data(), d_y);
    if (d_fixed) {
        zero_fixed_kernel<<<grid(nq), THREADS>>>(nq, d_fixed, d_y);
        check_cuda(cudaGetLastError(), "launch of the reduced product's fixed entries");
    }
}

void ReducedOperator::diagonal_blocks(double* d_out) const
{
    if (!m_A)
        throw std::logic_error("ReducedOperator::diagonal_blocks: not bound");
    const PeriodicView& m = m_map->view();
    const int d = m.dim, b2 = d * d;
    m_A->diagonal_blocks(m_full_diagonal.data());
    class_blocks_kernel<<<grid(size_t(m.num_classes) * size_t(b2)), THREADS>>>(m, m_full_diagonal.data(), d_out);
    check_cuda(cudaGetLastError(), "launch of the reduced class blocks");
    for (int i = 0; i < d; ++i)
        for (int k = 0; k < d; ++k) {
            unit_vector_kernel<<<grid(m_unit.size()), THREADS>>>(
                m_unit.size(), size_t(macro_dof(m, i, k)), m_unit.data());
            check_cuda(cudaGetLastError(), "launch of a reduced unit vector");
            multiply(m_unit.data(), m_column.data(), nullptr);
            macro_column_kernel<<<1, 32>>>(m, i, k, m_column.data(), d_out);
            check_cuda(cudaGetLastError(), "launch of a reduced macro column");
        }
    check_cuda(cudaDeviceSynchronize(), "the reduced diagonal blocks");
}

} // namespace diffipc::gpu
