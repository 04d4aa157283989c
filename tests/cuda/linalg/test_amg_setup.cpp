// The host-side setup of the smoothed-aggregation multigrid (cuda/linalg/amg_setup.hpp), on the CPU:
// the aggregation covers every vertex that is not excluded exactly once with connected aggregates
// and coarsens the graph; the tentative prolongator's columns are orthonormal per aggregate, zero
// on fixed dofs, and T R reproduces the rigid-body modes on the free dofs.

#include "cuda/linalg/amg_setup.hpp"
#include "cuda/linalg/bsr_pattern.hpp"
#include "tests/cuda/linalg/amg_test_utils.hpp"

#include <Eigen/LU>
#include <Eigen/SparseCholesky>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <queue>
#include <stdexcept>

using namespace diffipc;

namespace {

struct Graph {
    int num_vertices = 0;
    std::vector<int> row_offsets, col_indices;
    std::vector<double> rest;
};

Graph box_graph(int dim, const std::vector<int>& cells)
{
    const test::ElasticBox box = test::make_elastic_box(dim, cells, -1, 0.0, 0.0, 3);
    const gpu::ElementBsrPattern p
        = gpu::element_bsr_pattern(int(box.mesh.num_vertices()), dim + 1, box.elements_flat());
    return { p.num_vertices, p.row_offsets, p.col_indices, box.rest_flat() };
}

/// Whether aggregate `a`'s vertices are connected through the graph's edges between them.
bool connected(const Graph& g, const gpu::Aggregation& agg, int a)
{
    std::vector<int> members;
    for (int v = 0; v < g.num_vertices; ++v)
        if (agg.aggregate_of[size_t(v)] == a)
            members.push_back(v);
    if (members.empty())
        return false;
    std::vector<char> seen(size_t(g.num_vertices), 0);
    std::queue<int> queue;
    queue.push(members[0]);
    seen[size_t(members[0])] = 1;
    size_t reached = 0;
    while (!queue.empty()) {
        const int v = queue.front();
        queue.pop();
        ++reached;
        for (int k = g.row_offsets[size_t(v)]; k < g.row_offsets[size_t(v) + 1]; ++k) {
            const int u = g.col_indices[size_t(k)];
            if (!seen[size_t(u)] && agg.aggregate_of[size_t(u)] == a) {
                seen[size_t(u)] = 1;
                queue.push(u);
            }
        }
    }
    return reached == members.size();
}

} // namespace

TEST(AmgSetup, AggregatesCoverTheFreeVerticesOnceConnectedAndCoarsen)
{
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE(dim);
        const Graph g = box_graph(dim, dim == 2 ? std::vector<int> { 16, 9 } : std::vector<int> { 7, 6, 5 });
        // The vertices on the face x = 0 are excluded (all their dofs fixed).
        std::vector<char> excluded(size_t(g.num_vertices), 0);
        for (int v = 0; v < g.num_vertices; ++v)
            excluded[size_t(v)] = g.rest[size_t(v * dim)] == 0.0;
        const gpu::Aggregation agg = gpu::aggregate_vertices(g.num_vertices, g.row_offsets, g.col_indices, excluded);
        int covered = 0, wrong = 0;
        std::vector<int> sizes(size_t(agg.num_aggregates), 0);
        for (int v = 0; v < g.num_vertices; ++v) {
            const int a = agg.aggregate_of[size_t(v)];
            if (excluded[size_t(v)]) {
                wrong += a != -1;
                continue;
            }
            wrong += a < 0 || a >= agg.num_aggregates;
            if (a >= 0 && a < agg.num_aggregates) {
                ++covered;
                ++sizes[size_t(a)];
            }
        }
        EXPECT_EQ(wrong, 0);
        int disconnected = 0;
        for (int a = 0; a < agg.num_aggregates; ++a)
            disconnected += !connected(g, agg, a);
        EXPECT_EQ(disconnected, 0);
        EXPECT_EQ(*std::min_element(sizes.begin(), sizes.end()) > 0, true) << "an empty aggregate";
        // Coarsening: a vertex's neighbourhood holds about 7 (2D) or 15 (3D) vertices.
        EXPECT_LE(agg.num_aggregates * (dim == 2 ? 3 : 5), covered);
        // Deterministic.
        const gpu::Aggregation again = gpu::aggregate_vertices(g.num_vertices, g.row_offsets, g.col_indices, excluded);
        EXPECT_EQ(again.aggregate_of, agg.aggregate_of);
        std::printf("  %dD box, %d vertices (%d free): %d aggregates, sizes %d .. %d\n", dim, g.num_vertices, covered,
            agg.num_aggregates, *std::min_element(sizes.begin(), sizes.end()),
            *std::max_element(sizes.begin(), sizes.end()));
    }
}

TEST(AmgSetup, TentativeProlongatorIsOrthonormalAndReproducesTheRigidModes)
{
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE(dim);
        const Graph g = box_graph(dim, dim == 2 ? std::vector<int> { 12, 7 } : std::vector<int> { 5, 4, 4 });
        const int k = dim == 2 ? 3 : 6;
        const size_t n = size_t(g.num_vertices) * size_t(dim);
        // The face x = 0 clamped in y only: its vertices stay in aggregates with some fixed rows.
        std::vector<char> fixed(n, 0);
        for (int v = 0; v < g.num_vertices; ++v)
            if (g.rest[size_t(v * dim)] == 0.0)
                fixed[size_t(v * dim + 1)] = 1;
        const gpu::Aggregation agg = gpu::aggregate_vertices(g.num_vertices, g.row_offsets, g.col_indices);
        const std::vector<double> B = gpu::rigid_body_modes(dim, g.rest);
        const gpu::TentativeProlongator t = gpu::tentative_prolongator(agg, dim, k, B, fixed);
        ASSERT_EQ(t.blocks.size(), n * size_t(k));
        double orthonormal = 0, reproduced = 0, scale = 0;
        int fixed_nonzero = 0, inactive = 0;
        for (int a = 0; a < agg.num_aggregates; ++a) {
            std::vector<size_t> rows;
            for (size_t r = 0; r < n; ++r)
                if (agg.aggregate_of[r / size_t(dim)] == a)
                    rows.push_back(r);
            for (int i = 0; i < k; ++i) {
                inactive += !t.coarse_active[size_t(a * k + i)];
                for (int j = 0; j < k; ++j) {
                    double dot = 0;
                    for (const size_t r : rows)
                        dot += t.blocks[r * size_t(k) + size_t(i)] * t.blocks[r * size_t(k) + size_t(j)];
                    const bool active = t.coarse_active[size_t(a * k + i)] && t.coarse_active[size_t(a * k + j)];
                    orthonormal = std::max(orthonormal, std::abs(dot - (active && i == j ? 1.0 : 0.0)));
                }
            }
            // T R = B on the free rows.
            const double* R = t.coarse_modes.data() + size_t(a) * size_t(k * k);
            for (const size_t r : rows) {
                for (int j = 0; j < k; ++j) {
                    double tr = 0;
                    for (int l = 0; l < k; ++l)
                        tr += t.blocks[r * size_t(k) + size_t(l)] * R[l * k + j];
                    const double b = fixed[r] ? 0.0 : B[r * size_t(k) + size_t(j)];
                    reproduced = std::max(reproduced, std::abs(tr - b));
                    scale = std::max(scale, std::abs(b));
                }
                if (fixed[r])
                    for (int j = 0; j < k; ++j)
                        fixed_nonzero += t.blocks[r * size_t(k) + size_t(j)] != 0.0;
            }
        }
        EXPECT_LE(orthonormal, 1e-13);
        EXPECT_LE(reproduced, 1e-13 * scale);
        EXPECT_EQ(fixed_nonzero, 0);
        EXPECT_EQ(inactive, 0) << "every aggregate of this mesh determines every rigid mode";
        std::printf("  %dD box: %d aggregates, T^T T - I %.1e, T R - B %.1e relative\n", dim, agg.num_aggregates,
            orthonormal, reproduced / scale);
    }
}

TEST(AmgSetup, DegenerateAggregatesAndBadInput)
{
    // Two vertices on a line (one edge): 2D rigid modes have 3 columns; the rotation about the origin
    // is independent of the translations only if the points do not lie at one place. A single vertex
    // determines the two translations but not the rotation (its column is the translations' mix).
    const std::vector<int> offsets { 0, 1 }, cols { 0 };
    const gpu::Aggregation single = gpu::aggregate_vertices(1, offsets, cols);
    ASSERT_EQ(single.num_aggregates, 1);
    const std::vector<double> at { 2.0, 1.0 };
    const gpu::TentativeProlongator t = gpu::tentative_prolongator(single, 2, 3, gpu::rigid_body_modes(2, at));
    EXPECT_EQ(t.coarse_active, (std::vector<char> { 1, 1, 0 }));
    for (int i = 0; i < 2; ++i)
        EXPECT_EQ(t.blocks[size_t(i * 3 + 2)], 0.0);
    // All rows fixed: no mode survives.
    const gpu::TentativeProlongator none
        = gpu::tentative_prolongator(single, 2, 3, gpu::rigid_body_modes(2, at), std::vector<char> { 1, 1 });
    EXPECT_EQ(none.coarse_active, (std::vector<char> { 0, 0, 0 }));

    EXPECT_THROW(gpu::aggregate_vertices(2, offsets, cols), std::invalid_argument);
    EXPECT_THROW(gpu::aggregate_vertices(1, offsets, std::vector<int> { 3 }), std::invalid_argument);
    EXPECT_THROW(gpu::aggregate_vertices(1, offsets, cols, std::vector<char>(2, 0)), std::invalid_argument);
    EXPECT_THROW(gpu::rigid_body_modes(4, at), std::invalid_argument);
    EXPECT_THROW(gpu::tentative_prolongator(single, 2, 3, std::vector<double>(5, 0.0)), std::invalid_argument);
}

namespace {

/// Preconditioned CG on A (fixed dofs already identity rows) to relative residual tol: iterations.
template <typename Precondition>
int pcg_iterations(const SparseMatrixd& A, const VectorXd& b, double tol, Precondition precondition, VectorXd& x)
{
    x = VectorXd::Zero(b.size());
    VectorXd r = b, z = precondition(r), p = z;
    double rz = r.dot(z);
    const double stop = tol * b.norm();
    for (int it = 1; it <= 20000; ++it) {
        const VectorXd Ap = A * p;
        const double alpha = rz / p.dot(Ap);
        x += alpha * p;
        r -= alpha * Ap;
        if (r.norm() <= stop)
            return it;
        z = precondition(r);
        const double next = r.dot(z);
        p = z + (next / rz) * p;
        rz = next;
    }
    return -1;
}

} // namespace

TEST(AmgSetup, HostPrototypeOfTheTwoLevelPreconditionerCutsPcgIterations)
{
    // The plan's method on the CPU, before any device kernel: a two-level smoothed-aggregation V-cycle
    // (this file's aggregation and tentative prolongator, P = (I - w D^-1 A) T with w = 4 / (3 rho),
    // A_c = P^T A P solved directly, two damped block-Jacobi sweeps before and after: a symmetric
    // preconditioner) against block-Jacobi, in CG to 1e-12 (the adjoint's tolerance) on the Hessian of a
    // deformed neo-Hookean box with random Lame parameters per element, clamped at x = 0: the projected
    // one, and for the larger box also the true one, which the adjoint solves with.
    struct Case {
        std::vector<int> cells;
        bool project;
    };
    for (const Case& cs : { Case { { 16, 6, 6 }, true }, Case { { 32, 8, 8 }, true }, Case { { 32, 8, 8 }, false } }) {
        const std::vector<int>& cells = cs.cells;
        const int dim = 3, k = 6;
        const test::ElasticBox box = test::make_elastic_box(dim, cells, int(MaterialModel::NEO_HOOKEAN), 0.1, 0.1, 7);
        const Index n = box.mesh.num_dofs();
        std::vector<char> fixed(size_t(n), 0), excluded(size_t(box.mesh.num_vertices()), 0);
        for (Index v = 0; v < box.mesh.num_vertices(); ++v)
            if (box.mesh.rest_positions(v, 0) == 0.0) {
                excluded[size_t(v)] = 1;
                for (int i = 0; i < dim; ++i)
                    fixed[size_t(v * dim + i)] = 1;
            }
        // A with the fixed dofs' rows and columns replaced by identity ones.
        SparseMatrixd A = test::cpu_hessian(box, box.x, 1.0, cs.project);
        for (Index c = 0; c < A.outerSize(); ++c)
            for (SparseMatrixd::InnerIterator it(A, c); it; ++it)
                if (fixed[size_t(it.row())] || fixed[size_t(c)])
                    it.valueRef() = it.row() == c ? 1.0 : 0.0;
        const VectorXd b = [&] {
            VectorXd r = VectorXd::Random(n);
            for (Index i = 0; i < n; ++i)
                if (fixed[size_t(i)])
                    r[i] = 0;
            return r;
        }();
        const SparseMatrixd Dinv = test::inverse_block_diagonal(A, dim);
        VectorXd x_bj, x_amg;
        const int bj = pcg_iterations(
            A, b, 1e-12, [&](const VectorXd& r) -> VectorXd { return Dinv * r; }, x_bj);

        // The hierarchy.
        const gpu::ElementBsrPattern pattern
            = gpu::element_bsr_pattern(int(box.mesh.num_vertices()), dim + 1, box.elements_flat());
        const gpu::Aggregation agg
            = gpu::aggregate_vertices(pattern.num_vertices, pattern.row_offsets, pattern.col_indices, excluded);
        const gpu::TentativeProlongator t
            = gpu::tentative_prolongator(agg, dim, k, gpu::rigid_body_modes(dim, box.x_vector()), fixed);
        std::vector<Eigen::Triplet<double>> tt;
        std::vector<Index> column(size_t(agg.num_aggregates) * size_t(k), -1);
        Index nc = 0;
        for (size_t c = 0; c < column.size(); ++c)
            if (t.coarse_active[c])
                column[c] = nc++;
        for (Index r = 0; r < n; ++r) {
            const int a = agg.aggregate_of[size_t(r / dim)];
            if (a < 0)
                continue;
            for (int j = 0; j < k; ++j)
                if (column[size_t(a * k + j)] >= 0 && t.blocks[size_t(r * k + j)] != 0.0)
                    tt.emplace_back(r, column[size_t(a * k + j)], t.blocks[size_t(r * k + j)]);
        }
        SparseMatrixd T(n, nc);
        T.setFromTriplets(tt.begin(), tt.end());
        // rho(D^-1 A) by power iteration.
        VectorXd v = VectorXd::Ones(n);
        double rho = 0;
        for (int it = 0; it < 30; ++it) {
            const VectorXd w = Dinv * (A * v);
            rho = w.norm() / v.norm();
            v = w / w.norm();
        }
        const double omega = 4.0 / (3.0 * rho);
        const SparseMatrixd DinvA = Dinv * A;
        SparseMatrixd I(n, n);
        I.setIdentity();
        const SparseMatrixd P = (I - omega * DinvA) * T;
        const SparseMatrixd Ac = P.transpose() * A * P;
        const Eigen::SimplicialLDLT<SparseMatrixd> coarse(Ac);
        ASSERT_EQ(coarse.info(), Eigen::Success);
        const double smooth = 1.0 / rho; // damped block-Jacobi
        const auto vcycle = [&](const VectorXd& r) -> VectorXd {
            VectorXd z = VectorXd::Zero(n);
            for (int s = 0; s < 2; ++s)
                z += smooth * (Dinv * (r - A * z));
            const VectorXd rc = P.transpose() * (r - A * z);
            z += P * coarse.solve(rc);
            for (int s = 0; s < 2; ++s)
                z += smooth * (Dinv * (r - A * z));
            return z;
        };
        const int amg = pcg_iterations(A, b, 1e-12, vcycle, x_amg);
        const double agree = (x_amg - x_bj).norm() / x_bj.norm();
        std::printf("  box %dx%dx%d (%ld dofs), %s Hessian: %d aggregates, coarse %ld dofs; CG to 1e-12: "
                    "block-Jacobi %d iterations, two-level SA %d; solutions within %.1e\n",
            cells[0], cells[1], cells[2], long(n), cs.project ? "projected" : "true", agg.num_aggregates, long(nc), bj,
            amg, agree);
        ASSERT_GT(bj, 0);
        ASSERT_GT(amg, 0);
        EXPECT_LE(agree, 1e-9);
        EXPECT_LE(amg * 4, bj) << "the two-level preconditioner should cut the iterations at least fourfold";
    }
}
