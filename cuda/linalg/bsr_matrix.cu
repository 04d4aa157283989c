#include "cuda/linalg/bsr_matrix.hpp"

#include "cuda/common/device.hpp"

#include <cuda_runtime.h>

#include <algorithm>
#include <stdexcept>
#include <string>

namespace diffipc::gpu {

double HostBsrMatrix::coeff(int row, int col) const
{
    const int b = block_size, r = row / b, c = col / b;
    const auto first = col_indices.begin() + row_offsets[size_t(r)];
    const auto last = col_indices.begin() + row_offsets[size_t(r) + 1];
    const auto it = std::lower_bound(first, last, c);
    if (it == last || *it != c)
        return 0.0;
    const size_t k = size_t(it - col_indices.begin());
    return values[k * size_t(b * b) + size_t((row % b) * b + col % b)];
}

namespace {

    /// One thread per scalar row: y_r = sum over the row's blocks, in column order.
    template <int B>
    __global__ void bsr_multiply(int rows, const int* __restrict__ row_offsets, const int* __restrict__ cols,
        const double* __restrict__ values, const double* __restrict__ x, double* __restrict__ y,
        const unsigned char* __restrict__ fixed)
    {
        const int row = blockIdx.x * blockDim.x + threadIdx.x;
        if (row >= rows)
            return;
        if (fixed && fixed[row]) {
            y[row] = 0;
            return;
        }
        const int br = row / B, i = row % B;
        double acc = 0;
        for (int k = row_offsets[br]; k < row_offsets[br + 1]; ++k) {
            const int c = cols[k];
            const double* block = values + size_t(k) * (B * B) + i * B;
            for (int j = 0; j < B; ++j) {
                const int col = c * B + j;
                if (!fixed || !fixed[col])
                    acc += block[j] * x[col];
            }
        }
        y[row] = acc;
    }

    /// out[r b^2 + q] = entry q of block (r, r), or 0 if the row has none.
    template <int B>
    __global__ void bsr_diagonal_blocks(int block_rows, const int* __restrict__ row_offsets,
        const int* __restrict__ cols, const double* __restrict__ values, double* __restrict__ out)
    {
        const int br = blockIdx.x * blockDim.x + threadIdx.x;
        if (br >= block_rows)
            return;
        int slot = -1;
        for (int k = row_offsets[br]; k < row_offsets[br + 1]; ++k)
            if (cols[k] == br) {
                slot = k;
                break;
            }
        for (int q = 0; q < B * B; ++q)
            out[size_t(br) * (B * B) + q] = slot >= 0 ? values[size_t(slot) * (B * B) + q] : 0.0;
    }

} // namespace

void DeviceBsrMatrix::set_pattern(
    int block_size, const std::vector<int>& row_offsets, const std::vector<int>& col_indices)
{
    if (block_size != 2 && block_size != 3)
        throw std::invalid_argument("DeviceBsrMatrix: block size must be 2 or 3, not " + std::to_string(block_size));
    if (row_offsets.empty() || row_offsets.front() != 0 || size_t(row_offsets.back()) != col_indices.size())
        throw std::invalid_argument("DeviceBsrMatrix: row_offsets must run from 0 to #blocks");
    m_block_size = block_size;
    m_num_block_rows = int(row_offsets.size()) - 1;
    m_row_offsets = row_offsets;
    m_col_indices = col_indices;
    m_d_row_offsets.upload(row_offsets);
    m_d_col_indices.upload(col_indices);
    m_d_values.resize(col_indices.size() * size_t(block_size * block_size));
    m_d_values.set_zero();
}

void DeviceBsrMatrix::upload(const HostBsrMatrix& host)
{
    if (host.values.size() != host.col_indices.size() * size_t(host.block_size * host.block_size))
        throw std::invalid_argument("DeviceBsrMatrix: values must hold #blocks * b^2 entries");
    set_pattern(host.block_size, host.row_offsets, host.col_indices);
    m_d_values.upload(host.values);
}

HostBsrMatrix DeviceBsrMatrix::download() const
{
    HostBsrMatrix host;
    host.block_size = m_block_size;
    host.num_block_rows = m_num_block_rows;
    host.row_offsets = m_row_offsets;
    host.col_indices = m_col_indices;
    host.values = m_d_values.download();
    return host;
}

void DeviceBsrMatrix::set_zero() { m_d_values.set_zero(); }

void DeviceBsrMatrix::multiply(const double* d_x, double* d_y, const unsigned char* d_fixed) const
{
    const int rows = size();
    if (rows == 0)
        return;
    constexpr int THREADS = 256;
    const int blocks = (rows + THREADS - 1) / THREADS;
    if (m_block_size == 2)
        bsr_multiply<2><<<blocks, THREADS>>>(
            rows, m_d_row_offsets.data(), m_d_col_indices.data(), m_d_values.data(), d_x, d_y, d_fixed);
    else
        bsr_multiply<3><<<blocks, THREADS>>>(
            rows, m_d_row_offsets.data(), m_d_col_indices.data(), m_d_values.data(), d_x, d_y, d_fixed);
    check_cuda(cudaGetLastError(), "launch of the BSR matrix-vector product");
}

void DeviceBsrMatrix::diagonal_blocks(double* d_out) const
{
    const int rows = m_num_block_rows;
    if (rows == 0)
        return;
    constexpr int THREADS = 256;
    const int blocks = (rows + THREADS - 1) / THREADS;
    if (m_block_size == 2)
        bsr_diagonal_blocks<2>
            <<<blocks, THREADS>>>(rows, m_d_row_offsets.data(), m_d_col_indices.data(), m_d_values.data(), d_out);
    else
        bsr_diagonal_blocks<3>
            <<<blocks, THREADS>>>(rows, m_d_row_offsets.data(), m_d_col_indices.data(), m_d_values.data(), d_out);
    check_cuda(cudaGetLastError(), "launch of the BSR diagonal blocks");
}

} // namespace diffipc::gpu
