#pragma once
/// @file supernodal_cholesky.hpp
/// Sparse Cholesky A = L L^T whose numeric factorization runs on the thread pool.
///
/// CHOLMOD does the symbolic work (fill-reducing ordering, supernodes, the pattern
/// of L) and the triangular solves; the numeric factorization is ours, written into
/// CHOLMOD's supernodal factor. CHOLMOD's own numeric factorization visits the
/// supernodes one after the other and is parallel only inside BLAS calls, most of which
/// are too small to share (measured: 1.7x from 2 to 16 cores on a 112k-dof box). Here
/// a supernode is a task that runs as soon as its children in the supernodal
/// elimination tree are done (independent subtrees run concurrently), and a large
/// supernode splits its own work into a graph of tile tasks (descendant updates by
/// column and row block, then a tiled right-looking Cholesky of its panel in which each
/// tile's update, factorization or triangular solve runs as soon as its inputs are
/// final, with no barrier between the steps). Its triangular solves go by column
/// blocks too. Every BLAS call is single-threaded and every tile has a fixed size, so
/// the factor and the solutions are the same, bit for bit, for any thread count.
///
/// The algorithm is the left-looking supernodal Cholesky (Ng and Peyton 1993; the one
/// in CHOLMOD's cholmod_super_numeric): supernode s gathers its columns of A, subtracts
/// L_d L_d^T of every descendant d whose rows reach its columns, factors its
/// diagonal block (potrf) and solves for the rows below it (trsm).

#include "forward/common/types.hpp"

#include <memory>

namespace diffipc {

class SupernodalCholesky {
public:
    SupernodalCholesky();
    ~SupernodalCholesky();
    SupernodalCholesky(const SupernodalCholesky&) = delete;
    SupernodalCholesky& operator=(const SupernodalCholesky&) = delete;

    /// @brief Symbolic analysis of the pattern of `lower` (the lower triangle of a
    /// symmetric matrix): ordering, supernodes and the task schedule.
    /// @throws std::runtime_error if CHOLMOD's analysis fails (out of memory)
    void analyze(const SparseMatrixd& lower);
    /// @brief Numeric factorization of `lower`, whose pattern must lie within the analyzed
    /// one (entries absent from it are zeros of the analyzed pattern).
    /// @return false if the matrix is not positive definite (minor_column() says where)
    bool factorize(const SparseMatrixd& lower);
    /// Solves A x = b with the last successful factorization.
    VectorXd solve(const VectorXd& b) const;
    bool analyzed() const;
    /// The column (of the permuted matrix) where the last factorization broke down; the
    /// matrix size if it succeeded.
    Index minor_column() const;

    struct Statistics {
        Index supernodes = 0;
        Index tiled_supernodes = 0; ///< supernodes that split their own work into tiles
        double factor_entries = 0; ///< entries of L (with the explicit zeros of relaxed supernodes)
        double flops = 0; ///< floating-point operations of one numeric factorization
    };
    const Statistics& statistics() const;

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

} // namespace diffipc
