#pragma once
// Helpers shared by the multigrid's host and GPU tests: block-sparse values on a plan's patterns as
// Eigen matrices, a clamped elastic box's masked Hessian, and the tentative prolongator as a matrix.

#include "cuda/linalg/amg_hierarchy.hpp"
#include "cuda/linalg/bsr_pattern.hpp"
#include "tests/cuda/elastic_test_utils.hpp"

#include <Eigen/LU>

#include <vector>

namespace diffipc::test {

/// Values of row_block x col_block blocks (row-major) on `pattern` as a sparse matrix with
/// `num_cols` block columns.
inline SparseMatrixd block_matrix(
    const gpu::BlockPattern& pattern, int row_block, int col_block, int num_cols, const std::vector<double>& values)
{
    std::vector<Eigen::Triplet<double>> t;
    for (int r = 0; r < pattern.rows(); ++r)
        for (int e = pattern.offsets[size_t(r)]; e < pattern.offsets[size_t(r) + 1]; ++e)
            for (int i = 0; i < row_block; ++i)
                for (int j = 0; j < col_block; ++j)
                    t.emplace_back(r * row_block + i, pattern.cols[size_t(e)] * col_block + j,
                        values[size_t(e) * size_t(row_block * col_block) + size_t(i * col_block + j)]);
    SparseMatrixd S(pattern.rows() * row_block, num_cols * col_block);
    S.setFromTriplets(t.begin(), t.end());
    return S;
}

/// The values of a sparse matrix on a block pattern (entries outside it must be zero).
inline std::vector<double> block_values(const SparseMatrixd& A, const gpu::BlockPattern& pattern, int b)
{
    const Eigen::MatrixXd dense(A);
    std::vector<double> values;
    for (int r = 0; r < pattern.rows(); ++r)
        for (int e = pattern.offsets[size_t(r)]; e < pattern.offsets[size_t(r) + 1]; ++e)
            for (int i = 0; i < b; ++i)
                for (int j = 0; j < b; ++j)
                    values.push_back(dense(r * b + i, pattern.cols[size_t(e)] * b + j));
    return values;
}

/// The tentative prolongator of a level as a matrix (#dofs x #aggregates k).
inline SparseMatrixd tentative_matrix(const gpu::AmgLevelPlan& level, int num_aggregates)
{
    std::vector<Eigen::Triplet<double>> t;
    const int b = level.block, k = level.coarse_block;
    for (size_t v = 0; v < level.aggregate_of.size(); ++v) {
        const int a = level.aggregate_of[v];
        if (a >= 0)
            for (int i = 0; i < b; ++i)
                for (int j = 0; j < k; ++j)
                    t.emplace_back(int(v) * b + i, a * k + j, level.tentative[v * size_t(b * k) + size_t(i * k + j)]);
    }
    SparseMatrixd T(Index(level.aggregate_of.size()) * b, Index(num_aggregates) * k);
    T.setFromTriplets(t.begin(), t.end());
    return T;
}

/// A with the rows and columns of fixed dofs replaced by identity ones.
inline SparseMatrixd masked(SparseMatrixd A, const std::vector<char>& fixed)
{
    for (Index c = 0; c < A.outerSize(); ++c)
        for (SparseMatrixd::InnerIterator it(A, c); it; ++it)
            if (fixed[size_t(it.row())] || fixed[size_t(c)])
                it.valueRef() = it.row() == c ? 1.0 : 0.0;
    return A;
}

/// The inverse block diagonal (b x b blocks) of A.
inline SparseMatrixd inverse_block_diagonal(const SparseMatrixd& A, int b)
{
    std::vector<Eigen::Triplet<double>> t;
    for (Index v = 0; v < A.rows() / b; ++v) {
        const Eigen::MatrixXd inv = Eigen::MatrixXd(A.block(v * b, v * b, b, b)).inverse();
        for (int i = 0; i < b; ++i)
            for (int j = 0; j < b; ++j)
                t.emplace_back(v * b + i, v * b + j, inv(i, j));
    }
    SparseMatrixd D(A.rows(), A.cols());
    D.setFromTriplets(t.begin(), t.end());
    return D;
}

/// The dofs of the vertices on the face x_0 = 0 of a box.
inline std::vector<char> clamped_face(const ElasticBox& box)
{
    const int dim = box.mesh.dim;
    std::vector<char> fixed(size_t(box.mesh.num_dofs()), 0);
    for (Index v = 0; v < box.mesh.num_vertices(); ++v)
        if (box.mesh.rest_positions(v, 0) == 0.0)
            for (int i = 0; i < dim; ++i)
                fixed[size_t(v * dim + i)] = 1;
    return fixed;
}

/// The box's Hessian pattern as a BlockPattern.
inline gpu::BlockPattern box_pattern(const ElasticBox& box)
{
    const gpu::ElementBsrPattern p
        = gpu::element_bsr_pattern(int(box.mesh.num_vertices()), box.mesh.dim + 1, box.elements_flat());
    return { p.row_offsets, p.col_indices };
}

} // namespace diffipc::test
