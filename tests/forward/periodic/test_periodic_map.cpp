// The periodic cell's unknowns (forward/periodic/periodic_map.hpp): x = X + G X + w_c, checked
// against its definition vertex by vertex, for the tiling property, and for the transposed
// products the solver and adjoint use.

#include "forward/periodic/periodic_map.hpp"
#include "tests/forward/test_utils.hpp"

#include <gtest/gtest.h>


using namespace diffipc;

namespace {

Mesh cell(int dim)
{
    return dim == 2 ? box_mesh(2, (VectorXd(2) << -0.3, 0.1).finished(), (VectorXd(2) << 0.7, 0.6).finished(),
                          (VectorXi(2) << 4, 3).finished())
                    : box_mesh(3, VectorXd::Constant(3, 0.2), VectorXd::Constant(3, 1.2), (VectorXi(3) << 2, 3, 2).finished());
}

PeriodicPairing pairing_of(const Mesh& m)
{
    PeriodicBox box;
    box.lower = m.rest_positions.colwise().minCoeff().transpose();
    box.upper = m.rest_positions.colwise().maxCoeff().transpose();
    return pair_periodic_vertices(m, box, 1e-9, "mesh");
}

} // namespace

TEST(PeriodicMap, PositionsFollowTheDefinitionAndTile)
{
    for (int d : { 2, 3 }) {
        SCOPED_TRACE(d);
        const Mesh m = cell(d);
        const PeriodicPairing p = pairing_of(m);
        // An origin and a length: x = X + G (X - X_o) + w, q's macro entries L G.
        const VectorXd origin = 0.3 * test::random_vector(d, 21);
        const double L = 0.7;
        const PeriodicMap map(m, p, origin, L);
        ASSERT_EQ(map.num_reduced(), p.num_classes() * d + d * d);
        const VectorXd q = 0.1 * test::random_vector(map.num_reduced(), 3 + unsigned(d));
        const VectorXd x = map.positions(q);
        MatrixXd G(d, d);
        for (int i = 0; i < d; ++i)
            for (int j = 0; j < d; ++j)
                G(i, j) = q[map.macro_dof(i, j)] / L;
        for (Index v = 0; v < m.num_vertices(); ++v) {
            const VectorXd X = m.rest_positions.row(v).transpose();
            VectorXd w(d);
            for (int i = 0; i < d; ++i)
                w[i] = q[map.fluctuation_dof(p.vertex_class[v], i)];
            const VectorXd expected = X + G * (X - origin) + w;
            EXPECT_LE((x.segment(v * d, d) - expected).lpNorm<Eigen::Infinity>(), 1e-14) << "vertex " << v;
            // Tiling: a vertex and its class representative differ by (I + G) times their rest offset.
            const Index r = p.representative[p.vertex_class[v]];
            const VectorXd rest = X - m.rest_positions.row(r).transpose();
            const VectorXd deformed = x.segment(v * d, d) - x.segment(r * d, d);
            EXPECT_LE((deformed - (MatrixXd::Identity(d, d) + G) * rest).lpNorm<Eigen::Infinity>(), 1e-14);
        }
        // Positions and G give q back.
        EXPECT_LE((map.reduced(x, map.macro_gradient(q)) - q).lpNorm<Eigen::Infinity>(), 1e-14);
    }
}

TEST(PeriodicMap, ReductionsAreTheTransposedProducts)
{
    for (int d : { 2, 3 }) {
        SCOPED_TRACE(d);
        const Mesh m = cell(d);
        const PeriodicMap map(m, pairing_of(m));
        const Index n = m.num_dofs(), k = map.num_reduced();
        const VectorXd g = test::random_vector(n, 11), q = test::random_vector(k, 12);
        EXPECT_NEAR(map.reduce(g).dot(q), g.dot(map.expand(q)), 1e-12 * g.norm() * q.norm());
        // dE/dG of a gradient: sum_v g_v X_v^T (origin 0).
        MatrixXd expected_dG = MatrixXd::Zero(d, d);
        for (Index v = 0; v < m.num_vertices(); ++v)
            expected_dG += g.segment(v * d, d) * m.rest_positions.row(v);
        const VectorXd dG = map.macro_derivative(g);
        for (int i = 0; i < d; ++i)
            for (int j = 0; j < d; ++j)
                EXPECT_NEAR(dG[i * d + j], expected_dG(i, j), 1e-12 * expected_dG.norm());
        // A symmetric sparse matrix given by its lower triangle, against the dense product.
        MatrixXd A = MatrixXd::Zero(n, n);
        const VectorXd r = test::random_vector(n * 3, 13);
        for (Index i = 0; i < n; ++i) {
            A(i, i) = 4 + r[i];
            for (Index s = 1; s <= 2; ++s)
                if (i + s * d < n)
                    A(i + s * d, i) = A(i, i + s * d) = r[(i * 2 + s) % (n * 3)];
        }
        const SparseMatrixd full = A.sparseView();
        const SparseMatrixd lower = full.triangularView<Eigen::Lower>();
        const MatrixXd P = MatrixXd(map.matrix());
        const MatrixXd expected = P.transpose() * A * P;
        const MatrixXd got = MatrixXd(map.reduce_matrix(lower)).selfadjointView<Eigen::Lower>();
        EXPECT_LE((got - expected).lpNorm<Eigen::Infinity>(), 1e-12 * expected.lpNorm<Eigen::Infinity>());
    }
}
