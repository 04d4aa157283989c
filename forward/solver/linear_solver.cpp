#include "forward/solver/linear_solver.hpp"

#include "forward/common/timer.hpp"
#include "forward/scene/scene.hpp"
#include "forward/solver/supernodal_cholesky.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <Eigen/CholmodSupport>

#include <algorithm>
#include <vector>

namespace diffipc {

struct LinearSolver::Impl {
    SupernodalCholesky llt;
    Eigen::CholmodSimplicialLDLT<SparseMatrixd, Eigen::Lower> ldlt;
    bool llt_analyzed = false, ldlt_analyzed = false, last_ldlt = false;
    // The pattern the analyses were done for: contact can change it.
    std::vector<int> outer, inner;

    /// Is A's pattern contained in the analyzed one? Then the analysis (and its factor's
    /// pattern) still holds: entries absent from A are zeros of the analyzed pattern. A
    /// contact pattern that shrinks, or comes back to pairs seen before, needs no new analysis.
    bool within_pattern(const SparseMatrixd& A) const
    {
        if (A.rows() + 1 != Index(outer.size()) || A.nonZeros() > Index(inner.size()))
            return false;
        const int* ao = A.outerIndexPtr();
        const int* ai = A.innerIndexPtr();
        if (A.nonZeros() == Index(inner.size()))
            return std::equal(outer.begin(), outer.end(), ao) && std::equal(inner.begin(), inner.end(), ai);
        return tbb::parallel_reduce(
            tbb::blocked_range<Index>(0, A.cols(), 1024), true,
            [&](const tbb::blocked_range<Index>& r, bool ok) {
                for (Index c = r.begin(); ok && c < r.end(); ++c)
                    ok = std::includes(inner.begin() + outer[size_t(c)], inner.begin() + outer[size_t(c) + 1],
                        ai + ao[c], ai + ao[c + 1]);
                return ok;
            },
            [](bool a, bool b) { return a && b; });
    }
};

LinearSolver::LinearSolver(LinearSolverType type)
    : m_impl(std::make_unique<Impl>())
    , m_type(type)
{
    // A failed factorization is reported as a status; CHOLMOD need not print it.
    m_impl->ldlt.cholmod().print = 0;
}
LinearSolver::~LinearSolver() = default;

bool LinearSolver::cholesky_first() const { return m_type == LinearSolverType::CHOLMOD; }

bool LinearSolver::factorize(const SparseMatrixd& A, bool allow_fallback)
{
    m_used_fallback = false;
    if (!m_impl->within_pattern(A)) {
        m_impl->outer.assign(A.outerIndexPtr(), A.outerIndexPtr() + A.cols() + 1);
        m_impl->inner.assign(A.innerIndexPtr(), A.innerIndexPtr() + A.nonZeros());
        m_impl->llt_analyzed = m_impl->ldlt_analyzed = false;
    }
    if (m_type == LinearSolverType::CHOLMOD) {
        if (!m_impl->llt_analyzed) {
            Timer t;
            m_impl->llt.analyze(A);
            m_impl->llt_analyzed = true;
            ++m_analyses;
            t.add_to(m_analysis_time);
        }
        if (m_impl->llt.factorize(A)) {
            m_impl->last_ldlt = false;
            return true;
        }
        if (!allow_fallback)
            return false;
        m_used_fallback = true;
    }
    if (!m_impl->ldlt_analyzed) {
        Timer t;
        m_impl->ldlt.analyzePattern(A);
        m_impl->ldlt_analyzed = true;
        ++m_analyses;
        t.add_to(m_analysis_time);
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
