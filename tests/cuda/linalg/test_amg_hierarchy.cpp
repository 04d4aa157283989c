// The multigrid's symbolic plan (cuda/linalg/amg_hierarchy.hpp), on the CPU: its patterns, with the
// products evaluated on the host the way DeviceAmg's kernels evaluate them (sums over A's rows and P's
// columns, the other factor's block found in its row), give Eigen's (I - w D^-1 A) T, A P, P^T A P and
// P^T r on every level of a clamped elastic box's Hessian; the hierarchy coarsens to the requested size;
// the plan does not depend on the number of threads; bad input is refused.

#include "cuda/linalg/amg_hierarchy.hpp"
#include "tests/cuda/linalg/amg_test_utils.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <stdexcept>

using namespace diffipc;

namespace {

/// The index of block (row, column) in a pattern, or -1.
int find_block(const gpu::BlockPattern& pattern, int row, int column)
{
    for (int e = pattern.offsets[size_t(row)]; e < pattern.offsets[size_t(row) + 1]; ++e)
        if (pattern.cols[size_t(e)] == column)
            return e;
    return -1;
}

/// out (R x C) += X (R x S, or its transpose when X is S x R) times Y (S x C), row-major blocks.
void add_product(double* out, const double* X, const double* Y, int R, int S, int C, bool transpose_x)
{
    for (int i = 0; i < R; ++i)
        for (int j = 0; j < C; ++j)
            for (int s = 0; s < S; ++s)
                out[i * C + j] += (transpose_x ? X[s * R + i] : X[i * S + s]) * Y[s * C + j];
}

double relative_difference(const SparseMatrixd& A, const SparseMatrixd& B)
{
    return (Eigen::MatrixXd(A) - Eigen::MatrixXd(B)).norm() / Eigen::MatrixXd(B).norm();
}

void check_plan(int dim, const std::vector<int>& cells, int max_coarsest, int expected_levels)
{
    const test::ElasticBox box = test::make_elastic_box(dim, cells, int(MaterialModel::NEO_HOOKEAN), 0.1, 0.1, 11);
    const std::vector<char> fixed = test::clamped_face(box);
    const gpu::BlockPattern pattern = test::box_pattern(box);
    gpu::AmgPlanSettings settings;
    settings.max_coarsest_dofs = max_coarsest;
    const gpu::AmgPlan plan = gpu::plan_amg(dim, pattern, box.x_vector(), fixed, settings);
    ASSERT_EQ(int(plan.levels.size()), expected_levels);
    EXPECT_LE(plan.coarsest_size(), max_coarsest);

    SparseMatrixd A = test::masked(test::cpu_hessian(box, box.x, 1.0, true), fixed);
    std::printf("  %dD box, %ld dofs:", dim, long(A.rows()));
    for (const gpu::AmgLevelPlan& level : plan.levels) {
        const int b = level.block, k = level.coarse_block, n = level.matrix.rows();
        const int na = level.num_aggregates();
        ASSERT_EQ(A.rows(), Index(n) * b);
        // The level's matrix, on its pattern, masked with its fixed dofs.
        A = test::masked(A, level.fixed);
        const std::vector<double> a = test::block_values(A, level.matrix, b);
        ASSERT_LE(relative_difference(test::block_matrix(level.matrix, b, b, n, a), A), 1e-15)
            << "the level's matrix has entries outside its pattern";
        const SparseMatrixd T = test::tentative_matrix(level, na);
        const SparseMatrixd Dinv = test::inverse_block_diagonal(A, b);
        const double omega = 0.37;

        // P = T - w D^-1 (A T), (A T)'s block (v, a) summed over A's row v (w in aggregate a).
        const size_t bk = size_t(b * k);
        std::vector<double> at(size_t(level.prolongator.blocks()) * bk, 0.0), p(at.size());
        const Eigen::MatrixXd Dd(Dinv);
        for (int v = 0; v < n; ++v)
            for (int f = level.prolongator.offsets[size_t(v)]; f < level.prolongator.offsets[size_t(v) + 1]; ++f) {
                const int a_col = level.prolongator.cols[size_t(f)];
                for (int e = level.matrix.offsets[size_t(v)]; e < level.matrix.offsets[size_t(v) + 1]; ++e) {
                    const int w = level.matrix.cols[size_t(e)];
                    if (level.aggregate_of[size_t(w)] == a_col)
                        add_product(&at[size_t(f) * bk], &a[size_t(e) * size_t(b * b)],
                            &level.tentative[size_t(w) * bk], b, b, k, false);
                }
                for (int i = 0; i < b; ++i)
                    for (int j = 0; j < k; ++j) {
                        double dat = 0;
                        for (int c = 0; c < b; ++c)
                            dat += Dd(v * b + i, v * b + c) * at[size_t(f) * bk + size_t(c * k + j)];
                        const bool own = level.aggregate_of[size_t(v)] == a_col;
                        p[size_t(f) * bk + size_t(i * k + j)]
                            = (own ? level.tentative[size_t(v) * bk + size_t(i * k + j)] : 0.0) - omega * dat;
                    }
            }
        const SparseMatrixd P = test::block_matrix(level.prolongator, b, k, na, p);
        SparseMatrixd I(A.rows(), A.rows());
        I.setIdentity();
        const SparseMatrixd P_ref = (I - omega * Dinv * A) * T;
        EXPECT_LE(relative_difference(P, P_ref), 1e-14);

        // W = A P over A's rows, the P block found in its row; A_c = P^T W over P's columns.
        std::vector<double> w(size_t(level.product.blocks()) * bk, 0.0);
        for (int v = 0; v < n; ++v)
            for (int g = level.product.offsets[size_t(v)]; g < level.product.offsets[size_t(v) + 1]; ++g)
                for (int e = level.matrix.offsets[size_t(v)]; e < level.matrix.offsets[size_t(v) + 1]; ++e) {
                    const int f
                        = find_block(level.prolongator, level.matrix.cols[size_t(e)], level.product.cols[size_t(g)]);
                    if (f >= 0)
                        add_product(
                            &w[size_t(g) * bk], &a[size_t(e) * size_t(b * b)], &p[size_t(f) * bk], b, b, k, false);
                }
        const SparseMatrixd W_ref = A * P_ref;
        EXPECT_LE(relative_difference(test::block_matrix(level.product, b, k, na, w), W_ref), 1e-14);
        const gpu::BlockPattern& coarse = &level == &plan.levels.back() ? plan.coarsest : (&level + 1)->matrix;
        std::vector<double> ac(size_t(coarse.blocks()) * size_t(k * k), 0.0);
        for (int c = 0; c < na; ++c)
            for (int h = coarse.offsets[size_t(c)]; h < coarse.offsets[size_t(c) + 1]; ++h)
                for (int e = level.restriction.offsets[size_t(c)]; e < level.restriction.offsets[size_t(c) + 1]; ++e) {
                    const int f = level.restriction.first[size_t(e)], v = level.restriction.second[size_t(e)];
                    const int g = find_block(level.product, v, coarse.cols[size_t(h)]);
                    if (g >= 0)
                        add_product(
                            &ac[size_t(h) * size_t(k * k)], &p[size_t(f) * bk], &w[size_t(g) * bk], k, b, k, true);
                }
        const SparseMatrixd Ac = test::block_matrix(coarse, k, k, na, ac);
        const SparseMatrixd Ac_ref = P_ref.transpose() * A * P_ref;
        EXPECT_LE(relative_difference(Ac, Ac_ref), 1e-13);

        // The restriction list: P^T r.
        const VectorXd r = VectorXd::Random(A.rows());
        VectorXd rc = VectorXd::Zero(Index(na) * k);
        for (int c = 0; c < na; ++c)
            for (int e = level.restriction.offsets[size_t(c)]; e < level.restriction.offsets[size_t(c) + 1]; ++e) {
                const int f = level.restriction.first[size_t(e)], v = level.restriction.second[size_t(e)];
                for (int i = 0; i < k; ++i)
                    for (int s = 0; s < b; ++s)
                        rc[c * k + i] += p[size_t(f) * bk + size_t(s * k + i)] * r[v * b + s];
            }
        EXPECT_LE((rc - P_ref.transpose() * r).norm(), 1e-13 * (P_ref.transpose() * r).norm());
        // Fixed rows of P are zero (the plan's fixed dofs stay fixed).
        for (Index row = 0; row < P.rows(); ++row)
            if (level.fixed[size_t(row)])
                EXPECT_EQ(Eigen::RowVectorXd(Eigen::MatrixXd(P).row(row)).norm(), 0.0);
        std::printf(" %ld ->", long(A.rows()));
        A = Ac_ref;
    }
    std::printf(" %d dofs (coarsest)\n", plan.coarsest_size());
    ASSERT_EQ(A.rows(), plan.coarsest_size());
}

} // namespace

TEST(AmgHierarchy, PatternsHoldTheGalerkinProducts3D) { check_plan(3, { 16, 6, 6 }, 200, 2); }

TEST(AmgHierarchy, PatternsHoldTheGalerkinProducts2D) { check_plan(2, { 30, 12 }, 60, 2); }

TEST(AmgHierarchy, PlanDoesNotDependOnTheThreads)
{
    const test::ElasticBox box = test::make_elastic_box(3, { 40, 12, 12 }, -1, 0.1, 0.0, 9);
    const gpu::BlockPattern pattern = test::box_pattern(box);
    gpu::AmgPlanSettings one, two;
    one.threads = 1;
    two.threads = 2;
    const gpu::AmgPlan a = gpu::plan_amg(3, pattern, box.x_vector(), test::clamped_face(box), one);
    const gpu::AmgPlan b = gpu::plan_amg(3, pattern, box.x_vector(), test::clamped_face(box), two);
    ASSERT_EQ(a.levels.size(), b.levels.size());
    // 6,929 rows in chunks of 2,048: thread 0 builds chunks 0 and 2, thread 1 chunks 1 and 3; more than
    // 256 aggregates: the tentative prolongator's factorizations run on both threads.
    ASSERT_GT(a.levels.front().matrix.rows(), 3 * 2048) << "threads with two chunks";
    ASSERT_GT(a.levels.front().num_aggregates(), 256) << "factorizations on two threads";
    for (size_t l = 0; l < a.levels.size(); ++l) {
        const gpu::AmgLevelPlan &x = a.levels[l], &y = b.levels[l];
        EXPECT_EQ(x.prolongator.cols, y.prolongator.cols);
        EXPECT_EQ(x.prolongator.offsets, y.prolongator.offsets);
        EXPECT_EQ(x.product.cols, y.product.cols);
        EXPECT_EQ(x.product.offsets, y.product.offsets);
        EXPECT_EQ(x.restriction.offsets, y.restriction.offsets);
        EXPECT_EQ(x.restriction.first, y.restriction.first);
        EXPECT_EQ(x.restriction.second, y.restriction.second);
        EXPECT_EQ(x.aggregate_of, y.aggregate_of);
        EXPECT_EQ(x.tentative, y.tentative);
        EXPECT_EQ(x.fixed, y.fixed);
    }
    EXPECT_EQ(a.coarsest.cols, b.coarsest.cols);
    EXPECT_EQ(a.coarsest.offsets, b.coarsest.offsets);
    EXPECT_EQ(a.coarsest_fixed, b.coarsest_fixed);
}

TEST(AmgHierarchy, SmallMatrixIsItsOwnCoarsestLevel)
{
    const test::ElasticBox box = test::make_elastic_box(3, { 3, 2, 2 }, -1, 0.0, 0.0, 5);
    const gpu::AmgPlan plan = gpu::plan_amg(3, test::box_pattern(box), box.x_vector(), test::clamped_face(box));
    EXPECT_TRUE(plan.levels.empty());
    EXPECT_EQ(plan.coarsest_size(), int(box.mesh.num_dofs()));
    EXPECT_EQ(plan.coarsest_fixed, test::clamped_face(box));
}

TEST(AmgHierarchy, RefusesBadInput)
{
    const test::ElasticBox box = test::make_elastic_box(2, { 3, 2 }, -1, 0.0, 0.0, 5);
    const gpu::BlockPattern pattern = test::box_pattern(box);
    const std::vector<double> x = box.x_vector();
    EXPECT_THROW(gpu::plan_amg(4, pattern, x, {}), std::invalid_argument);
    EXPECT_THROW(gpu::plan_amg(2, pattern, std::vector<double>(3, 0.0), {}), std::invalid_argument);
    EXPECT_THROW(gpu::plan_amg(2, pattern, x, std::vector<char>(1, 0)), std::invalid_argument);
    gpu::BlockPattern no_diagonal = pattern;
    no_diagonal.cols[0] = no_diagonal.cols[0] == 0 ? 1 : 0; // row 0 loses its diagonal block
    gpu::AmgPlanSettings tiny;
    tiny.max_coarsest_dofs = 1;
    EXPECT_THROW(gpu::plan_amg(2, no_diagonal, x, {}, tiny), std::invalid_argument);
    gpu::BlockPattern decreasing = pattern;
    std::swap(decreasing.offsets[1], decreasing.offsets[2]);
    EXPECT_THROW(gpu::plan_amg(2, decreasing, x, {}), std::invalid_argument);
    gpu::AmgPlanSettings negative;
    negative.threads = -1;
    EXPECT_THROW(gpu::plan_amg(2, pattern, x, {}, negative), std::invalid_argument);
    gpu::BlockPattern out_of_range = pattern;
    out_of_range.cols.back() = 1000;
    EXPECT_THROW(gpu::plan_amg(2, out_of_range, x, {}), std::invalid_argument);
}
