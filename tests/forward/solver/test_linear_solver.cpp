// The linear solver (forward/solver/linear_solver.cpp): Cholesky first, CHOLMOD's LDL^T as the
// fallback for a matrix that is not positive definite, and no fallback when it is not allowed.

#include "forward/scene/scene.hpp"
#include "forward/solver/linear_solver.hpp"

#include <gtest/gtest.h>

#include <random>
#include <vector>

using namespace diffipc;

namespace {

/// Lower triangle of diag(L + shift I, -1): L the Laplacian of a chain of n vertices with random
/// positive edge weights (singular: the constant vector is its null space; shift > 0 makes it
/// positive definite), and one negative diagonal entry so that Cholesky fails.
SparseMatrixd chain_with_negative_entry(int n, double shift, unsigned seed)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> weight(0.5, 2.0);
    std::vector<Eigen::Triplet<double>> t;
    std::vector<double> diagonal(size_t(n), shift);
    for (int i = 0; i + 1 < n; ++i) {
        const double w = weight(rng);
        diagonal[size_t(i)] += w;
        diagonal[size_t(i + 1)] += w;
        t.emplace_back(i + 1, i, -w);
    }
    for (int i = 0; i < n; ++i)
        t.emplace_back(i, i, diagonal[size_t(i)]);
    t.emplace_back(n, n, -1.0);
    SparseMatrixd A(n + 1, n + 1);
    A.setFromTriplets(t.begin(), t.end());
    return A;
}

TEST(LinearSolver, IndefiniteMatrixFallsBackToLdlt)
{
    for (unsigned seed = 0; seed < 20; ++seed) {
        LinearSolver solver(LinearSolverType::CHOLMOD);
        const SparseMatrixd A = chain_with_negative_entry(30, 1e-3, seed);
        ASSERT_TRUE(solver.factorize(A, true)) << "seed " << seed;
        EXPECT_TRUE(solver.used_fallback());
        // The solution solves the full (symmetric) system.
        const SparseMatrixd full = SparseMatrixd(A.selfadjointView<Eigen::Lower>());
        const VectorXd b = VectorXd::LinSpaced(A.rows(), -1.0, 1.0);
        const VectorXd x = solver.solve(b);
        EXPECT_LE((full * x - b).norm(), 1e-9 * b.norm()) << "seed " << seed;
    }
}

TEST(LinearSolver, WithoutFallbackAnIndefiniteMatrixIsRefused)
{
    LinearSolver solver(LinearSolverType::CHOLMOD);
    EXPECT_FALSE(solver.factorize(chain_with_negative_entry(30, 1e-3, 1), false));
}

} // namespace
