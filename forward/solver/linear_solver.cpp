#include "forward/solver/linear_solver.hpp"

#include "forward/scene/scene.hpp"

#include <Eigen/CholmodSupport>

#include <algorithm>
#include <vector>

namespace diffipc {

struct LinearSolver::Impl {
    Eigen::CholmodSupernodalLLT<SparseMatrixd, Eigen::Lower> llt;
    Eigen::CholmodSimplicialLDLT<SparseMatrixd, Eigen::Lower> ldlt;
    bool llt_analyzed = false, ldlt_analyzed = false, last_ldlt = false;
    // The pattern the analyses were done for: contact can change it.
    std::vector<int> outer, inner;

    bool same_pattern(const SparseMatrixd& A) const
    {
        return A.rows() + 1 == Index(outer.size()) && A.nonZeros() == Index(inner.size())
            && std::equal(outer.begin(), outer.end(), A.outerIndexPtr())
            && std::equal(inner.begin(), inner.end(), A.innerIndexPtr());
    }
};

LinearSolver::LinearSolver(LinearSolverType type)
    : m_impl(std::make_unique<Impl>())
    , m_type(type)
{
    // A failed factorization is reported as a status; CHOLMOD need not print it.
    m_impl->llt.cholmod().print = 0;
    m_impl->ldlt.cholmod().print = 0;
}
LinearSolver::~LinearSolver() = default;

bool LinearSolver::cholesky_first() const { return m_type == LinearSolverType::CHOLMOD; }

bool LinearSolver::factorize(const SparseMatrixd& A, bool allow_fallback)
{
    m_used_fallback = false;
    if (!m_impl->same_pattern(A)) {
        m_impl->outer.assign(A.outerIndexPtr(), A.outerIndexPtr() + A.cols() + 1);
        m_impl->inner.assign(A.innerIndexPtr(), A.innerIndexPtr() + A.nonZeros());
        m_impl->llt_analyzed = m_impl->ldlt_analyzed = false;
    }
    if (m_type == LinearSolverType::CHOLMOD) {
        if (!m_impl->llt_analyzed) {
            m_impl->llt.analyzePattern(A);
            m_impl->llt_analyzed = true;
            ++m_analyses;
        }
        m_impl->llt.factorize(A);
        if (m_impl->llt.info() == Eigen::Success) {
            m_impl->last_ldlt = false;
            return true;
        }
        if (!allow_fallback)
            return false;
        m_used_fallback = true;
    }
    if (!m_impl->ldlt_analyzed) {
        m_impl->ldlt.analyzePattern(A);
        m_impl->ldlt_analyzed = true;
        ++m_analyses;
    }
    m_impl->ldlt.factorize(A);
    m_impl->last_ldlt = true;
    return m_impl->ldlt.info() == Eigen::Success;
}

VectorXd LinearSolver::solve(const VectorXd& b) const
{
    if (m_impl->last_ldlt)
        return m_impl->ldlt.solve(b);
    return m_impl->llt.solve(b);
}

} // namespace diffipc
