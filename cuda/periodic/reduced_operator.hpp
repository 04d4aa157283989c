#pragma once
/// @file reduced_operator.hpp
/// A periodic cell's Newton matrix in its reduced unknowns, P^T A P (forward/periodic/periodic_potential.hpp
/// on the CPU), as a DeviceLinearOperator that DevicePCG solves with: A is a full-space operator, P a
/// periodic map (device_periodic_map.hpp). Without contact A is the elastic matrix and P the cell's map;
/// with contact across the boundary DeviceNewton sums two (OperatorSum): P^T H P and P_s^T C P_s, the
/// contact's Hessian C on the image surface with the surface's own map P_s.
/// q's blocks are the classes' fluctuations (C blocks of dim), then the macro gradient's rows (dim blocks
/// of dim: L G(i, 0 .. dim - 1)).
///
/// The product: y = P^T (A (P x)), with a fixed mask in q zeroing x's and y's fixed entries first and last
/// (P^T A P restricted to the free entries, DeviceLinearOperator's contract).
///
/// The diagonal blocks, for the block-Jacobi preconditioner:
/// - a class's block is the sum of its vertices' diagonal blocks of A. The exact block also has A's blocks
///   between two vertices of the class, which exist where an element joins two copies of one vertex (a
///   cell one element thick across a periodic axis) or, for P_s^T C P_s, where a contact pair joins a
///   vertex and an image of it; there the preconditioner is that approximation (PCG's iterations, not
///   its solution, depend on it).
/// - a macro row's block is exact: each of its dim columns is a product P^T A P e, dim^2 products in all.
///
/// DeviceNewton's periodic mode (set_periodic) uses it.
/// Host code; this header compiles with a plain C++ compiler (no CUDA headers).

#include "cuda/linalg/device_array.hpp"
#include "cuda/linalg/linear_operator.hpp"
#include "cuda/periodic/device_periodic_map.hpp"

namespace diffipc::gpu {

class ReducedOperator : public DeviceLinearOperator {
public:
    /// @brief Binds A and the map (kept by reference: both must outlive this object's use).
    /// @throws std::invalid_argument if A's block size or block rows do not fit the map's dim and vertices
    void bind(const DeviceLinearOperator& A, DevicePeriodicMap& map);

    int block_size() const override { return m_map ? m_map->dim() : 0; }
    /// The classes, then the macro gradient's dim rows.
    int num_block_rows() const override { return m_map ? m_map->num_classes() + m_map->dim() : 0; }

    using DeviceLinearOperator::multiply; // the host-vector form
    /// @brief d_y = P^T A P d_x, or with d_fixed (size() bytes) the free entries' restriction. Asynchronous.
    void multiply(const double* d_x, double* d_y, const unsigned char* d_fixed = nullptr) const override;
    /// @brief d_out = the preconditioner's diagonal blocks (the class blocks as the file comment says, the
    /// macro blocks exact), #block rows * dim^2 doubles, block r row-major at r dim^2. Synchronizes.
    void diagonal_blocks(double* d_out) const override;

private:
    const DeviceLinearOperator* m_A = nullptr;
    DevicePeriodicMap* m_map = nullptr;
    mutable DeviceArray<double> m_q, m_x, m_y, m_unit, m_column, m_full_diagonal;
};

/// A + B of two operators of the same shape (a periodic cell's elastic and contact parts, each a
/// ReducedOperator): the products' sum, the diagonal blocks' sum.
class OperatorSum : public DeviceLinearOperator {
public:
    /// @brief Binds A and B (kept by reference).
    /// @throws std::invalid_argument if their block sizes or block rows differ
    void bind(const DeviceLinearOperator& A, const DeviceLinearOperator& B);

    int block_size() const override { return m_A ? m_A->block_size() : 0; }
    int num_block_rows() const override { return m_A ? m_A->num_block_rows() : 0; }
    using DeviceLinearOperator::multiply; // the host-vector form
    /// @brief d_y = A d_x + B d_x (with d_fixed: each restricted to the free entries). Asynchronous.
    void multiply(const double* d_x, double* d_y, const unsigned char* d_fixed = nullptr) const override;
    /// @brief d_out = A's diagonal blocks + B's. Synchronizes.
    void diagonal_blocks(double* d_out) const override;

private:
    const DeviceLinearOperator *m_A = nullptr, *m_B = nullptr;
    mutable DeviceArray<double> m_y, m_blocks;
};

} // namespace diffipc::gpu
