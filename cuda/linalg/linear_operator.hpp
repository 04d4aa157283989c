#pragma once
/// @file linear_operator.hpp
/// A square matrix on the GPU as DevicePCG (device_pcg.hpp) sees it: its product with a vector
/// and its b by b diagonal blocks (for the block-Jacobi preconditioner). DeviceBsrMatrix is one;
/// SumOperator (cuda/contact/sum_operator.hpp), the elastic matrix plus the contact matrix
/// without a union pattern, is another. Host API (plain C++); vectors are device pointers of
/// size() doubles, flattened vertex-major (xyzxyz).

#include <vector>

namespace diffipc::gpu {

class DeviceLinearOperator {
public:
    virtual ~DeviceLinearOperator() = default;

    /// b, 2 or 3 (the spatial dimension).
    virtual int block_size() const = 0;
    /// Block rows (= vertices).
    virtual int num_block_rows() const = 0;
    /// Rows (= columns) of the scalar matrix.
    int size() const { return num_block_rows() * block_size(); }

    /// @brief d_y = A d_x, or with d_fixed (size() bytes, nonzero = fixed dof) d_y = P A P d_x where P
    /// zeroes the fixed dofs. Deterministic (each row summed in a fixed order). Asynchronous.
    virtual void multiply(const double* d_x, double* d_y, const unsigned char* d_fixed) const = 0;
    /// @brief d_out = the diagonal blocks, #block rows * b^2 doubles (block r row-major at r b^2; zero
    /// where the pattern has no diagonal block). Asynchronous.
    virtual void diagonal_blocks(double* d_out) const = 0;

    /// @brief y = A x with host vectors (size() each; copied up and back); synchronizes.
    /// @throws std::invalid_argument if x has not size() entries
    std::vector<double> multiply(const std::vector<double>& x) const;
};

} // namespace diffipc::gpu
