#pragma once
/// @file linear_solver.hpp
/// Sparse symmetric solves for Newton: supernodal Cholesky (CHOLMOD's analysis and
/// solves, our parallel numeric factorization: supernodal_cholesky.hpp) with the
/// symbolic analysis done once for the fixed pattern and reused across
/// iterations and time steps; if the numeric Cholesky fails (matrix not
/// positive definite) CHOLMOD's LDL^T is tried on the same pattern.

#include "forward/common/types.hpp"

#include <memory>

namespace diffipc {

enum class LinearSolverType;

class LinearSolver {
public:
    explicit LinearSolver(LinearSolverType type);
    ~LinearSolver();

    /// @brief Numeric factorization of the lower triangle of A (symbolic
    /// analysis on the first call, and again when the pattern changes).
    /// Returns false on breakdown.
    /// @param allow_fallback try LDL^T when Cholesky fails; without it a matrix
    ///        that is not positive definite is simply reported (false)
    bool factorize(const SparseMatrixd& A, bool allow_fallback = true);
    /// True if the configured solver is Cholesky first (CHOLMOD).
    bool cholesky_first() const;
    /// @brief Solves A x = b with the last successful factorization.
    VectorXd solve(const VectorXd& b) const;
    /// True if the last factorization had to fall back to LDL^T.
    bool used_fallback() const { return m_used_fallback; }
    int analyses() const { return m_analyses; }
    /// Seconds spent in symbolic analyses so far.
    double analysis_time() const { return m_analysis_time; }

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
    LinearSolverType m_type;
    bool m_used_fallback = false;
    int m_analyses = 0;
    double m_analysis_time = 0;
};

} // namespace diffipc
