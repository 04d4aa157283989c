#pragma once
/// @file bsr_matrix.hpp
/// Square block-sparse (BSR) matrices in GPU memory with b by b blocks (b = 2 or 3, the
/// spatial dimension: one block per vertex pair), and their product with a vector. Host
/// API (plain C++, no CUDA types); vectors passed as device pointers are #rows = #block
/// rows * b doubles, flattened vertex-major (xyzxyz).
///
/// Layout: block row r holds the blocks (r, col_indices[k]) for k in
/// [row_offsets[r], row_offsets[r + 1]), columns increasing; block k's entries are
/// values[k b^2 + i b + j] (row-major within the block), the matrix entry
/// (r b + i, col_indices[k] b + j). Both triangles are stored.

#include "cuda/linalg/device_array.hpp"
#include "cuda/linalg/linear_operator.hpp"

#include <vector>

namespace diffipc::gpu {

/// A BSR matrix on the host (the layout above).
struct HostBsrMatrix {
    int block_size = 0;
    int num_block_rows = 0;
    std::vector<int> row_offsets; ///< #block rows + 1
    std::vector<int> col_indices; ///< #blocks
    std::vector<double> values; ///< #blocks * b^2

    int size() const { return num_block_rows * block_size; }
    /// @brief Entry (row, col) of the matrix (0 outside the pattern).
    double coeff(int row, int col) const;
};

class DeviceBsrMatrix : public DeviceLinearOperator {
public:
    /// @brief Sets the pattern (copied to the device) and zeroes the values.
    /// @param block_size  b, 2 or 3
    /// @param row_offsets #block rows + 1, @param col_indices #blocks (layout above)
    void set_pattern(int block_size, const std::vector<int>& row_offsets, const std::vector<int>& col_indices);
    /// @brief Pattern and values from a host matrix.
    void upload(const HostBsrMatrix& host);
    HostBsrMatrix download() const;
    void set_zero();

    int block_size() const override { return m_block_size; }
    int num_block_rows() const override { return m_num_block_rows; }
    int num_blocks() const { return int(m_col_indices.size()); }
    /// Rows (= columns) of the scalar matrix, #block rows * b.
    int size() const { return m_num_block_rows * m_block_size; }
    DeviceBsrMatrix() = default;
    DeviceBsrMatrix(DeviceBsrMatrix&&) = default;
    DeviceBsrMatrix& operator=(DeviceBsrMatrix&&) = default;

    /// Device pointers to the pattern and the values (layout above).
    const int* device_row_offsets() const { return m_d_row_offsets.data(); }
    const int* device_col_indices() const { return m_d_col_indices.data(); }
    double* device_values() { return m_d_values.data(); }
    const double* device_values() const { return m_d_values.data(); }
    /// The pattern, as kept on the host.
    const std::vector<int>& row_offsets() const { return m_row_offsets; }
    const std::vector<int>& col_indices() const { return m_col_indices; }

    /// @brief d_y = A d_x, or with d_fixed (size() bytes, nonzero = fixed dof) d_y = P A P d_x where P
    /// zeroes the fixed dofs. Each row's sum runs over its blocks in increasing column order: the
    /// result does not depend on the scheduling. Asynchronous (default stream).
    void multiply(const double* d_x, double* d_y, const unsigned char* d_fixed = nullptr) const override;
    /// @brief d_out = the diagonal blocks (DeviceLinearOperator). Asynchronous.
    void diagonal_blocks(double* d_out) const override;
    using DeviceLinearOperator::multiply; // y = A x with host vectors

private:
    int m_block_size = 0;
    int m_num_block_rows = 0;
    std::vector<int> m_row_offsets, m_col_indices;
    DeviceArray<int> m_d_row_offsets, m_d_col_indices;
    DeviceArray<double> m_d_values;
};

} // namespace diffipc::gpu
