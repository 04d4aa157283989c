#include "cuda/contact/sum_operator.hpp"

#include "cuda/common/device.hpp"

#include <cuda_runtime.h>

#include <stdexcept>
#include <string>

namespace diffipc::gpu {

namespace {

    constexpr int THREADS = 256;

    int grid(size_t n) { return int((n + THREADS - 1) / THREADS); }

    void check_launch(const char* what) { check_cuda(cudaGetLastError(), what); }

    /// y[row] += (C x)[row] for the scalar rows of C's nonempty block rows, blocks in column order.
    template <int B>
    __global__ void add_rows_product(int num_rows, const int* __restrict__ rows, const int* __restrict__ row_offsets,
        const int* __restrict__ cols, const double* __restrict__ values, const double* __restrict__ x,
        double* __restrict__ y, const unsigned char* __restrict__ fixed)
    {
        const int t = blockIdx.x * blockDim.x + threadIdx.x;
        if (t >= num_rows * B)
            return;
        const int br = rows[t / B], i = t % B, row = br * B + i;
        if (fixed && fixed[row])
            return; // A's product set it to 0
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
        y[row] += acc;
    }

    /// out[t] = (a slot ? A : 0) + (c slot ? C : 0), entry t = slot b^2 + q of the target pattern.
    __global__ void sum_entries(size_t entries, int b2, const int* __restrict__ a_slot, const int* __restrict__ c_slot,
        const double* __restrict__ a_values, const double* __restrict__ c_values, double* __restrict__ out)
    {
        const size_t t = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (t >= entries)
            return;
        const size_t s = t / size_t(b2), q = t % size_t(b2);
        const int a = a_slot[s], c = c_slot[s];
        const double va = a >= 0 ? a_values[size_t(a) * b2 + q] : 0.0;
        const double vc = c >= 0 ? c_values[size_t(c) * b2 + q] : 0.0;
        out[t] = a >= 0 && c >= 0 ? va + vc : a >= 0 ? va : vc;
    }

    /// Slot of the diagonal block of each block row, or -1.
    std::vector<int> diagonal_slots(const DeviceBsrMatrix& M)
    {
        const std::vector<int>& offsets = M.row_offsets();
        const std::vector<int>& cols = M.col_indices();
        std::vector<int> slots(size_t(M.num_block_rows()), -1);
        for (int r = 0; r < M.num_block_rows(); ++r)
            for (int k = offsets[size_t(r)]; k < offsets[size_t(r) + 1]; ++k)
                if (cols[size_t(k)] == r) {
                    slots[size_t(r)] = k;
                    break;
                }
        return slots;
    }

    /// The block rows of M with at least one block.
    std::vector<int> nonempty_rows(const DeviceBsrMatrix& M)
    {
        const std::vector<int>& offsets = M.row_offsets();
        std::vector<int> rows;
        for (int r = 0; r < M.num_block_rows(); ++r)
            if (offsets[size_t(r) + 1] > offsets[size_t(r)])
                rows.push_back(r);
        return rows;
    }

    /// out[r b^2 + q] += F's diagonal block of row r, entry q (where it has one).
    __global__ void add_diagonal(size_t entries, int b2, const int* __restrict__ slot,
        const double* __restrict__ values, double* __restrict__ out)
    {
        const size_t t = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
        if (t >= entries)
            return;
        const int s = slot[t / size_t(b2)];
        if (s >= 0)
            out[t] += values[size_t(s) * b2 + t % size_t(b2)];
    }

    /// y += (M x) over M's nonempty block rows `rows` (a DeviceArray of them).
    void add_rows(int block_size, const DeviceArray<int>& rows, const DeviceBsrMatrix& M, const double* d_x,
        double* d_y, const unsigned char* d_fixed)
    {
        const int nr = int(rows.size());
        if (nr == 0)
            return;
        const size_t n = size_t(nr) * size_t(block_size);
        if (block_size == 2)
            add_rows_product<2><<<grid(n), THREADS>>>(
                nr, rows.data(), M.device_row_offsets(), M.device_col_indices(), M.device_values(), d_x, d_y, d_fixed);
        else
            add_rows_product<3><<<grid(n), THREADS>>>(
                nr, rows.data(), M.device_row_offsets(), M.device_col_indices(), M.device_values(), d_x, d_y, d_fixed);
        check_launch("launch of the contact rows' product");
    }

} // namespace

void SumOperator::bind(const DeviceBsrMatrix& A, const DeviceBsrMatrix& C, const DeviceBsrMatrix* F)
{
    for (const DeviceBsrMatrix* M : { &C, F })
        if (M && (A.block_size() != M->block_size() || A.num_block_rows() != M->num_block_rows()))
            throw std::invalid_argument("SumOperator: A has " + std::to_string(A.num_block_rows())
                + " block rows of size " + std::to_string(A.block_size()) + ", an addend "
                + std::to_string(M->num_block_rows()) + " of size " + std::to_string(M->block_size()));
    const bool same_a = m_A == &A && m_a_blocks == A.num_blocks() && m_num_block_rows == A.num_block_rows();
    m_A = &A;
    m_C = &C;
    m_block_size = A.block_size();
    m_num_block_rows = A.num_block_rows();
    m_union_built = false;
    m_F = F;
    m_c_rows.upload(nonempty_rows(C));
    if (!same_a) {
        m_a_diagonal.upload(diagonal_slots(A));
        m_a_blocks = A.num_blocks();
    }
    m_c_diagonal.upload(diagonal_slots(C));
    if (F) {
        m_f_rows.upload(nonempty_rows(*F));
        m_f_diagonal.upload(diagonal_slots(*F));
    }
}

void SumOperator::build_union() const
{
    if (!m_A)
        throw std::logic_error("SumOperator: bind() first");
    if (m_F)
        throw std::logic_error("SumOperator: the union pattern is A + C's; a third addend is bound");
    if (m_union_built)
        return;
    const int rows = m_num_block_rows;
    const std::vector<int>&ao = m_A->row_offsets(), &ac = m_A->col_indices();
    const std::vector<int>&co = m_C->row_offsets(), &cc = m_C->col_indices();
    // The union pattern, row by row: a merge of two increasing column lists.
    m_row_offsets.assign(size_t(rows) + 1, 0);
    m_col_indices.clear();
    m_col_indices.reserve(ac.size() + cc.size());
    std::vector<int> a_slot, c_slot;
    a_slot.reserve(ac.size() + cc.size());
    c_slot.reserve(ac.size() + cc.size());
    for (int r = 0; r < rows; ++r) {
        int i = ao[size_t(r)], j = co[size_t(r)];
        const int ie = ao[size_t(r) + 1], je = co[size_t(r) + 1];
        while (i < ie || j < je) {
            const int ca = i < ie ? ac[size_t(i)] : -1, cb = j < je ? cc[size_t(j)] : -1;
            if (j >= je || (i < ie && ca < cb)) {
                m_col_indices.push_back(ca);
                a_slot.push_back(i++);
                c_slot.push_back(-1);
            } else if (i >= ie || cb < ca) {
                m_col_indices.push_back(cb);
                a_slot.push_back(-1);
                c_slot.push_back(j++);
            } else {
                m_col_indices.push_back(ca);
                a_slot.push_back(i++);
                c_slot.push_back(j++);
            }
        }
        m_row_offsets[size_t(r) + 1] = int(m_col_indices.size());
    }
    m_a_slot.upload(a_slot);
    m_c_slot.upload(c_slot);
    m_union_built = true;
}

void SumOperator::multiply(const double* d_x, double* d_y, const unsigned char* d_fixed) const
{
    if (!m_A)
        throw std::logic_error("SumOperator::multiply: bind() first");
    m_A->multiply(d_x, d_y, d_fixed);
    add_rows(m_block_size, m_c_rows, *m_C, d_x, d_y, d_fixed);
    if (m_F)
        add_rows(m_block_size, m_f_rows, *m_F, d_x, d_y, d_fixed);
}

void SumOperator::diagonal_blocks(double* d_out) const
{
    if (!m_A)
        throw std::logic_error("SumOperator::diagonal_blocks: bind() first");
    const int b2 = m_block_size * m_block_size;
    const size_t entries = size_t(m_num_block_rows) * size_t(b2);
    if (entries == 0)
        return;
    sum_entries<<<grid(entries), THREADS>>>(
        entries, b2, m_a_diagonal.data(), m_c_diagonal.data(), m_A->device_values(), m_C->device_values(), d_out);
    check_launch("launch of the diagonal blocks' sum");
    if (m_F) {
        add_diagonal<<<grid(entries), THREADS>>>(entries, b2, m_f_diagonal.data(), m_F->device_values(), d_out);
        check_launch("launch of the friction diagonal blocks' sum");
    }
}

DeviceBsrMatrix SumOperator::make_sum_matrix() const
{
    build_union();
    DeviceBsrMatrix S;
    S.set_pattern(m_block_size, m_row_offsets, m_col_indices);
    return S;
}

void SumOperator::assemble_sum(DeviceBsrMatrix& S) const
{
    build_union();
    if (S.block_size() != m_block_size || S.row_offsets() != m_row_offsets || S.col_indices() != m_col_indices)
        throw std::invalid_argument(
            "SumOperator::assemble_sum: S does not have the union pattern (make it with make_sum_matrix())");
    const int b2 = m_block_size * m_block_size;
    const size_t entries = m_col_indices.size() * size_t(b2);
    if (entries == 0)
        return;
    sum_entries<<<grid(entries), THREADS>>>(
        entries, b2, m_a_slot.data(), m_c_slot.data(), m_A->device_values(), m_C->device_values(), S.device_values());
    check_launch("launch of the matrix sum");
}

} // namespace diffipc::gpu
