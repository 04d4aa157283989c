#pragma once
/// @file device_pcg.hpp
/// Preconditioned conjugate gradients on the GPU for a symmetric positive definite matrix given
/// as a DeviceLinearOperator (linear_operator.hpp: a BSR matrix, bsr_matrix.hpp, or the sum of the
/// elastic and contact matrices, cuda/contact/sum_operator.hpp), with a block-Jacobi preconditioner (the inverted b by
/// b diagonal blocks) or one the caller gives (device_preconditioner.hpp: the multigrid, device_amg.hpp), and
/// Dirichlet-fixed dofs.
///
/// Fixed dofs are eliminated: with P the diagonal 0/1 matrix that zeroes them, the solve is
/// (P A P + I - P) x = P b, i.e. A_ff x_f = b_f on the free dofs and x = 0 on the fixed ones.
/// The preconditioner inverts each diagonal block with its fixed rows and columns replaced by
/// identity ones (a block that is not positive definite falls back to its inverted diagonal,
/// or 1 where that is not positive).
///
/// With a constraint (set_constraint: one direction a on the free dofs), the solve is projected PCG
/// (Gould, Hribar and Nocedal 2001): x minimizes 1/2 x^T A x - b^T x over the free dofs with a^T x = 0,
/// which needs A positive definite on that hyperplane only (an indefinite A past a limit point can
/// be). The preconditioner M is replaced by M - (M a)(M a)^T / (a^T M a), whose outputs are orthogonal
/// to a, and every residual loses its component along a (Euclidean projection), the constraint's
/// multiplier times a: r, ||P b|| and the reported residual are those projected ones.
///
/// Stopping: ||r_k|| <= relative_tolerance ||P b|| for the recursively updated residual r_k
/// (2-norms), or max_iterations, or a breakdown (p^T A p <= 0 or not finite: A is not positive
/// definite on the free dofs); the result reports the true residual ||P (b - A x)|| / ||P b||,
/// recomputed at the end. Every dot product is a fixed-order reduction (reduction.hpp) and the
/// matrix-vector product sums each row in a fixed order, so two solves of the same system give
/// bitwise equal iterates. All vectors stay on the device; one copy of 6 doubles to the host per
/// iteration decides whether to stop.

#include "cuda/linalg/bsr_matrix.hpp"
#include "cuda/linalg/device_array.hpp"
#include "cuda/linalg/device_preconditioner.hpp"
#include "cuda/linalg/linear_operator.hpp"

#include <vector>

namespace diffipc::gpu {

struct PcgSettings {
    /// Stop once ||r|| <= relative_tolerance ||P b|| (> 0).
    double relative_tolerance = 1e-10;
    /// Iteration cap (>= 0).
    int max_iterations = 10000;
};

struct PcgResult {
    /// Iterations performed (matrix-vector products, not counting the final residual check).
    int iterations = 0;
    /// True residual ||P (b - A x)|| / ||P b|| at the returned x (0 when P b = 0).
    double relative_residual = 0;
    /// The recursive residual met the tolerance.
    bool converged = false;
    /// Stopped on p^T A p <= 0 or a non-finite value; x is the last iterate before it.
    bool breakdown = false;
};

class DevicePCG {
public:
    DevicePCG() = default;
    explicit DevicePCG(const PcgSettings& settings)
        : m_settings(settings)
    {
    }

    PcgSettings& settings() { return m_settings; }
    const PcgSettings& settings() const { return m_settings; }

    /// @brief Sets the Dirichlet-fixed dofs: #dofs flags, nonzero = fixed (as
    /// SparseAssembler::apply_constraints' `constrained`); an empty vector fixes none.
    void set_fixed_dofs(const std::vector<char>& fixed);

    /// @brief Restricts the following solves to a^T x = 0 (file comment); nullptr: unconstrained again.
    /// @param d_a A.size() doubles on the device, zero on the fixed dofs and not all zero; read at each
    ///            solve, so it must stay valid while set (solve_device throws std::invalid_argument if a
    ///            is zero or not finite)
    void set_constraint(const double* d_a) { m_constraint = d_a; }
    const double* constraint() const { return m_constraint; }

    /// @brief Solves for x from x = 0 (layout and semantics in the file comment).
    /// @param A   symmetric positive definite on the free dofs, b by b blocks (device)
    /// @param d_b right-hand side, A.size() doubles on the device
    /// @param d_x out: solution, A.size() doubles on the device (fixed entries 0)
    /// @param preconditioner instead of block-Jacobi, if given (A.size() rows, symmetric positive definite,
    ///        keeping the fixed entries 0)
    PcgResult solve_device(const DeviceLinearOperator& A, const double* d_b, double* d_x,
        const DevicePreconditioner* preconditioner = nullptr);
    /// @brief The same with host vectors (b and x: A.size() doubles, flattened vertex-major).
    PcgResult solve(const DeviceBsrMatrix& A, const std::vector<double>& b, std::vector<double>& x);

private:
    void prepare(int n, int block_size, int num_block_rows);

    PcgSettings m_settings;
    DeviceArray<unsigned char> m_fixed; // empty: no fixed dofs
    const double* m_constraint = nullptr; // a of set_constraint
    DeviceArray<double> m_constraint_image; // M a
    DeviceArray<double> m_r, m_z, m_p, m_q, m_diagonal, m_inverse_diagonal, m_partials, m_scalars;
};

} // namespace diffipc::gpu
