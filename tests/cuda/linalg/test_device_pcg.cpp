// DevicePCG (cuda/linalg/device_pcg.hpp) on the GPU: the projected Newton system of an elastic box
// with a Dirichlet face, against a CPU direct solve; repeatability; breakdown. Skipped without a GPU.

#include "cuda/elastic/device_elastic_mesh.hpp"
#include "cuda/linalg/device_pcg.hpp"
#include "tests/cuda/elastic_test_utils.hpp"

#include <Eigen/SparseCholesky>
#include <gtest/gtest.h>

#include <cstdio>

using namespace diffipc;

namespace {

void solve_newton_system(int dim, const std::vector<int>& cells)
{
    const test::ElasticBox box = test::make_elastic_box(dim, cells, -1, 0.15, 0.1, 31 + unsigned(dim));
    gpu::DeviceElasticMesh m;
    m.upload(dim, box.rest_flat(), box.elements_flat(), box.model_codes(), box.mu_vector(), box.lambda_vector());
    const std::vector<double> x = box.x_vector();
    const gpu::DeviceBsrMatrix& H = m.hessian_bsr(x, true);
    std::vector<double> b = m.gradient(x);
    for (double& v : b)
        v = -v;

    // Dirichlet: the face at x_0 = 0.
    std::vector<char> fixed(x.size(), 0);
    for (Index v = 0; v < box.mesh.num_vertices(); ++v)
        if (box.mesh.rest_positions(v, 0) == 0)
            for (int i = 0; i < dim; ++i)
                fixed[size_t(v * dim + i)] = 1;

    gpu::DevicePCG pcg(gpu::PcgSettings { 1e-10, 10000 });
    pcg.set_fixed_dofs(fixed);
    std::vector<double> p;
    const gpu::PcgResult result = pcg.solve(H, b, p);
    EXPECT_TRUE(result.converged);
    EXPECT_FALSE(result.breakdown);
    // The recursive residual met 1e-10; the true one drifts from it by round-off (about eps cond(A)).
    EXPECT_LE(result.relative_residual, 3e-10);
    for (size_t k = 0; k < p.size(); ++k)
        if (fixed[k])
            EXPECT_EQ(p[k], 0.0);

    // CPU: the same system with the fixed rows and columns made identity ones, by LDL^T.
    SparseAssembler assembler;
    assembler.build(dim, box.mesh.num_vertices(), box.mesh.elements);
    assembler.set_zero();
    box.potential->add_hessian(box.x, 1.0, true, assembler);
    assembler.apply_constraints(fixed);
    const SparseMatrixd A = assembler.matrix().selfadjointView<Eigen::Lower>();
    VectorXd rhs = Eigen::Map<const VectorXd>(b.data(), Index(b.size()));
    for (size_t k = 0; k < fixed.size(); ++k)
        if (fixed[k])
            rhs[Index(k)] = 0;
    Eigen::SimplicialLDLT<SparseMatrixd> ldlt(A);
    ASSERT_EQ(ldlt.info(), Eigen::Success);
    const VectorXd p_cpu = ldlt.solve(rhs);
    const Eigen::Map<const VectorXd> p_gpu(p.data(), Index(p.size()));
    const double difference = (p_gpu - p_cpu).norm() / p_cpu.norm();
    EXPECT_LE(difference, 1e-8);
    EXPECT_LE((rhs - A * p_gpu).norm() / rhs.norm(), 3e-10) << "the residual with the CPU's matrix";
    std::printf("dim %d, %d dofs: %d PCG iterations, relative residual %.2e, relative difference to LDL^T %.2e\n", dim,
        m.num_dofs(), result.iterations, result.relative_residual, difference);

    // A second solve gives the same bits.
    std::vector<double> again;
    const gpu::PcgResult second = pcg.solve(H, b, again);
    EXPECT_EQ(second.iterations, result.iterations);
    EXPECT_EQ(again, p);
}

TEST(DevicePCG, SolvesProjectedNewtonSystemWithDirichletFace3D)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    solve_newton_system(3, { 5, 4, 3 });
}

TEST(DevicePCG, SolvesProjectedNewtonSystemWithDirichletFace2D)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    solve_newton_system(2, { 12, 9 });
}

/// diag(-1, ..., -1) in 2 by 2 blocks.
gpu::HostBsrMatrix negative_identity(int block_rows)
{
    gpu::HostBsrMatrix A;
    A.block_size = 2;
    A.num_block_rows = block_rows;
    for (int r = 0; r <= block_rows; ++r)
        A.row_offsets.push_back(r);
    for (int r = 0; r < block_rows; ++r) {
        A.col_indices.push_back(r);
        A.values.insert(A.values.end(), { -1.0, 0.0, 0.0, -1.0 });
    }
    return A;
}

TEST(DevicePCG, ReportsBreakdownOnANegativeDefiniteMatrix)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    gpu::DeviceBsrMatrix A;
    A.upload(negative_identity(3));
    gpu::DevicePCG pcg;
    std::vector<double> x;
    const gpu::PcgResult r = pcg.solve(A, { 1, 2, 3, 4, 5, 6 }, x);
    EXPECT_TRUE(r.breakdown);
    EXPECT_FALSE(r.converged);
    EXPECT_EQ(x, std::vector<double>(6, 0.0));
}

TEST(DevicePCG, ZeroRightHandSideAndAllFixed)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    gpu::HostBsrMatrix host = negative_identity(2);
    for (double& v : host.values)
        v = -v; // identity
    gpu::DeviceBsrMatrix A;
    A.upload(host);
    gpu::DevicePCG pcg;
    std::vector<double> x;
    gpu::PcgResult r = pcg.solve(A, { 0, 0, 0, 0 }, x);
    EXPECT_TRUE(r.converged);
    EXPECT_EQ(r.iterations, 0);
    EXPECT_EQ(x, std::vector<double>(4, 0.0));
    pcg.set_fixed_dofs({ 1, 1, 1, 1 });
    r = pcg.solve(A, { 1, 2, 3, 4 }, x);
    EXPECT_TRUE(r.converged);
    EXPECT_EQ(x, std::vector<double>(4, 0.0));
    // Identity with one fixed dof: one iteration.
    pcg.set_fixed_dofs({ 0, 1, 0, 0 });
    r = pcg.solve(A, { 1, 2, 3, 4 }, x);
    EXPECT_TRUE(r.converged);
    EXPECT_EQ(x, (std::vector<double> { 1, 0, 3, 4 }));
    EXPECT_THROW(
        {
            pcg.set_fixed_dofs({ 0, 1 });
            pcg.solve(A, { 1, 2, 3, 4 }, x);
        },
        std::invalid_argument);
}

} // namespace
