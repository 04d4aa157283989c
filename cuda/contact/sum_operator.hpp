#pragma once
/// @file sum_operator.hpp
/// The Newton matrix of a contact scene as the sum A + C (+ F) of BSR matrices with different
/// patterns (cuda/linalg/bsr_matrix.hpp): A on the elastic mesh's fixed pattern
/// (DeviceElasticMesh, plus inertia on its diagonal blocks), C on the contact pattern of the
/// current pair list (DeviceBarrier, rebuilt whenever the pairs change), and optionally F on the
/// lagged friction pairs' pattern (DeviceFriction, rebuilt at each lagging). All have the same
/// number of block rows (#V) and block size (dim).
///
/// Two ways to solve with it:
/// - assemble_sum(): S = A + C on the union of the two patterns (built on the host by bind(),
///   merging each block row's sorted columns), entry by entry; S is an ordinary DeviceBsrMatrix,
///   so today's DevicePCG solves with it unchanged (its block-Jacobi diagonal then includes the
///   contact diagonal blocks). Costs one pass over A's values per Newton iteration, and an
///   O(#blocks of A) merge on the host per pair list.
/// - as a DeviceLinearOperator (cuda/linalg/linear_operator.hpp), which DevicePCG solves with:
///   multiply() and diagonal_blocks() give the product y = A x + C x and the block diagonal of
///   A + C without forming S; no union pattern needed, and each product reads C's few rows only.
///   This is what DeviceNewton uses.
///
/// bind() costs O(#block rows + #blocks of C) on the host when only C changed (A's diagonal slots
/// are kept while A is the same matrix with the same number of blocks); the union pattern is
/// built on first use by make_sum_matrix(), assemble_sum() or sum_row_offsets().
///
/// Determinism: (A x)_r is summed by A's product as always, then (C x)_r over C's blocks in
/// column order is added; S's entries are a + c (or the one that exists). Both are fixed orders:
/// repeated calls give the same bits (but multiply() and S's product round differently).

#include "cuda/linalg/bsr_matrix.hpp"
#include "cuda/linalg/device_array.hpp"
#include "cuda/linalg/linear_operator.hpp"

#include <vector>

namespace diffipc::gpu {

class SumOperator : public DeviceLinearOperator {
public:
    /// @brief Binds A and C (kept by reference: they must outlive this object's use, and C must be
    /// bound again whenever its pattern changes, A whenever its pattern changes). Finds the diagonal
    /// slots and C's nonempty rows on the host and uploads them.
    /// @throws std::invalid_argument if the block sizes or the numbers of block rows differ
    void bind(const DeviceBsrMatrix& A, const DeviceBsrMatrix& C) { bind(A, C, nullptr); }
    /// @brief bind(A, C) with a third addend F (nullptr: none) on a pattern of its own (lagged friction's
    /// pairs): the operator is A + C + F; its product adds F's rows after C's, its diagonal blocks F's
    /// after A + C's. The union pattern (make_sum_matrix, assemble_sum) is A + C's only: with F bound
    /// they throw std::logic_error.
    void bind(const DeviceBsrMatrix& A, const DeviceBsrMatrix& C, const DeviceBsrMatrix* F);

    int block_size() const override { return m_block_size; }
    int num_block_rows() const override { return m_num_block_rows; }

    /// @brief d_y = (A + C) d_x, or with d_fixed (size() bytes, nonzero = fixed) P (A + C) P d_x as
    /// DeviceBsrMatrix::multiply. Asynchronous.
    void multiply(const double* d_x, double* d_y, const unsigned char* d_fixed = nullptr) const override;
    /// @brief d_out = the diagonal blocks of A + C, #block rows * b^2 doubles (block r row-major at
    /// r b^2). Asynchronous.
    void diagonal_blocks(double* d_out) const override;

    /// @brief A zero matrix on the union pattern of A and C.
    DeviceBsrMatrix make_sum_matrix() const;
    /// @brief S = A + C entrywise (S from make_sum_matrix()). Asynchronous.
    /// @throws std::invalid_argument if S does not have the union pattern
    void assemble_sum(DeviceBsrMatrix& S) const;
    /// The union pattern (host copy): #block rows + 1 offsets and block columns.
    const std::vector<int>& sum_row_offsets() const
    {
        build_union();
        return m_row_offsets;
    }
    const std::vector<int>& sum_col_indices() const
    {
        build_union();
        return m_col_indices;
    }

    /// @brief y = (A + C) x with host vectors (size() each); synchronizes.
    using DeviceLinearOperator::multiply;

private:
    /// The union pattern and the slot maps (once per bind()).
    void build_union() const;

    const DeviceBsrMatrix* m_A = nullptr;
    const DeviceBsrMatrix* m_C = nullptr;
    int m_block_size = 0, m_num_block_rows = 0;
    int m_a_blocks = -1; // A's number of blocks when its diagonal slots were found
    mutable bool m_union_built = false;
    mutable std::vector<int> m_row_offsets, m_col_indices; // union pattern
    const DeviceBsrMatrix* m_F = nullptr;
    DeviceArray<int> m_c_rows, m_f_rows; // block rows of C (F) with blocks
    DeviceArray<int> m_a_diagonal, m_c_diagonal, m_f_diagonal; // per block row: slot of its diagonal block, or -1
    mutable DeviceArray<int> m_a_slot, m_c_slot; // per union slot: the slot in A / C, or -1
};

} // namespace diffipc::gpu
