#include "forward/fem/fe_space.hpp"
#include "forward/potentials/elastic_potential.hpp"
#include "forward/solver/sparse_assembler.hpp"
#include "tests/forward/test_utils.hpp"

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <random>
#include <set>

using namespace diffipc;

namespace {

TEST(SparseAssembler, ColorsShareNoVertexAndCoverAllElements)
{
    const Mesh m = box_mesh(3, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 1), Eigen::Vector3i(4, 3, 3));
    SparseAssembler H;
    H.build(3, m.num_vertices(), m.elements);
    Index count = 0;
    for (const auto& color : H.colors()) {
        std::set<int> seen;
        for (Index e : color)
            for (int a = 0; a < 4; ++a)
                EXPECT_TRUE(seen.insert(m.elements(e, a)).second) << "vertex shared within a color";
        count += Index(color.size());
    }
    EXPECT_EQ(count, m.num_elements());
}

// The parallel fixed-pattern assembly equals a dense sum of element Hessians
// computed one by one through the element-level function.
TEST(SparseAssembler, ElasticHessianEqualsDenseElementSum)
{
    for (int dim : { 2, 3 }) {
        const Mesh m = dim == 2
            ? box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1), Eigen::Vector2i(3, 4))
            : box_mesh(3, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 1), Eigen::Vector3i(2, 2, 3));
        const FESpace space(m);
        const Index ne = m.num_elements();
        std::vector<MaterialModel> models(static_cast<size_t>(ne), MaterialModel::NEO_HOOKEAN);
        VectorXd mu = VectorXd::LinSpaced(ne, 1.0, 2.0), lambda = VectorXd::LinSpaced(ne, 3.0, 1.0);
        ElasticPotential psi(space, models, mu, lambda);
        const VectorXd x = flatten(m.rest_positions) + 0.03 * test::random_vector(m.num_dofs(), 9);
        SparseAssembler H;
        H.build(dim, m.num_vertices(), m.elements);
        for (bool project : { false, true }) {
            H.set_zero();
            psi.add_hessian(x, 2.0, project, H);
            MatrixXd dense = MatrixXd::Zero(m.num_dofs(), m.num_dofs());
            const Positions P = unflatten(x, dim);
            for (Index e = 0; e < ne; ++e) {
                MatrixXd rest(dim + 1, dim), def(dim + 1, dim);
                for (int a = 0; a <= dim; ++a) {
                    rest.row(a) = m.rest_positions.row(m.elements(e, a));
                    def.row(a) = P.row(m.elements(e, a));
                }
                const MatrixXd Ke = element_hessian(MaterialModel::NEO_HOOKEAN, rest, def, mu[e], lambda[e], project);
                for (int a = 0; a < dim * (dim + 1); ++a)
                    for (int b = 0; b < dim * (dim + 1); ++b)
                        dense(m.elements(e, a / dim) * dim + a % dim, m.elements(e, b / dim) * dim + b % dim)
                            += 2.0 * Ke(a, b);
            }
            const SparseMatrixd full = H.matrix().selfadjointView<Eigen::Lower>();
            const MatrixXd assembled(full);
            EXPECT_LT((assembled - dense).norm(), 1e-12 * dense.norm()) << "dim " << dim << " project " << project;
        }
    }
}

TEST(SparseAssembler, ConstraintsBecomeIdentityRows)
{
    const Mesh m = box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1), Eigen::Vector2i(2, 2));
    SparseAssembler H;
    H.build(2, m.num_vertices(), m.elements);
    for (Index i = 0; i < H.size(); ++i)
        H.add_diagonal(i, 5.0);
    std::vector<char> constrained(static_cast<size_t>(H.size()), 0);
    constrained[3] = 1;
    H.apply_constraints(constrained);
    const SparseMatrixd full = H.matrix().selfadjointView<Eigen::Lower>();
    const MatrixXd A(full);
    EXPECT_EQ(A(3, 3), 1.0);
    EXPECT_EQ(A.row(3).sum(), 1.0);
    EXPECT_EQ(A(4, 4), 5.0);
}

// Local (contact) matrices between vertices that share no element: the merged matrix
// equals the dense sum over repeated assemblies whose local sets grow, shrink (the
// remembered pattern keeps old pairs as zeros) and are filled concurrently.
TEST(SparseAssembler, LocalMatricesEqualDenseSum)
{
    const Mesh m = box_mesh(3, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 1), Eigen::Vector3i(3, 2, 2));
    const Index nv = m.num_vertices(), n = m.num_dofs();
    SparseAssembler H;
    H.build(3, nv, m.elements);
    std::mt19937 rng(5);
    std::uniform_int_distribution<Index> vertex(0, nv - 1);
    // Local sets of 2-4 distinct vertices with symmetric random matrices; every set
    // shares vertex 0 with the next (several locals on one column).
    auto make = [&](int count) {
        std::vector<std::pair<std::vector<Index>, MatrixXd>> locals;
        for (int k = 0; k < count; ++k) {
            std::set<Index> v { k % 2 ? Index(0) : vertex(rng) };
            const size_t size = size_t(2 + k % 3);
            while (v.size() < size)
                v.insert(vertex(rng));
            std::vector<Index> verts(v.begin(), v.end());
            std::shuffle(verts.begin(), verts.end(), rng);
            const MatrixXd R
                = test::random_vector(Index(9 * size * size), k + 1).reshaped(Index(3 * size), Index(3 * size));
            locals.emplace_back(verts, R + R.transpose());
        }
        return locals;
    };
    const auto big = make(40);
    const std::vector<std::pair<std::vector<Index>, MatrixXd>> small(big.begin(), big.begin() + 10);
    for (const auto* set : { &big, &small, &big }) {
        H.set_zero();
        for (Index d = 0; d < n; ++d)
            H.add_diagonal(d, 1.0);
        MatrixXd dense = MatrixXd::Identity(n, n);
        const size_t half = set->size() / 2;
        for (size_t k = 0; k < half; ++k)
            H.add_local((*set)[k].first.data(), int((*set)[k].first.size()), (*set)[k].second.data());
        const size_t first = H.reserve_locals(set->size() - half);
        tbb::parallel_for(size_t(half), set->size(), [&](size_t k) {
            H.set_local(first + k - half, (*set)[k].first.data(), int((*set)[k].first.size()), (*set)[k].second.data());
        });
        for (const auto& [verts, K] : *set)
            for (size_t a = 0; a < verts.size(); ++a)
                for (size_t b = 0; b < verts.size(); ++b)
                    dense.block(verts[a] * 3, verts[b] * 3, 3, 3) += K.block(Index(3 * a), Index(3 * b), 3, 3);
        H.finalize();
        const SparseMatrixd full = H.matrix().selfadjointView<Eigen::Lower>();
        const MatrixXd assembled(full);
        EXPECT_LT((assembled - dense).norm(), 1e-13 * dense.norm()) << set->size() << " locals";
    }
}

} // namespace
