// DevicePCG (cuda/linalg/device_pcg.hpp) on the GPU: the projected Newton system of an elastic box
// with a Dirichlet face, against a CPU direct solve; repeatability; breakdown; the solve on a hyperplane
// (set_constraint) against the dense KKT system. Skipped without a GPU.

#include "cuda/elastic/device_elastic_mesh.hpp"
#include "cuda/linalg/device_pcg.hpp"
#include "tests/cuda/elastic_test_utils.hpp"

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

using namespace diffipc;

namespace {

void solve_newton_system(int dim, const std::vector<int>& cells)
{
    const test::ElasticBox box = test::make_elastic_box(dim, cells, -1, 0.15, 0.1, 31 + unsigned(dim));
    gpu::DeviceElasticMesh m;
    m.upload(dim, box.rest_flat(), box.elements_flat(), box.models, box.mu_vector(), box.lambda_vector());
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

/// The solve on the hyperplane a^T x = 0 (set_constraint) against the dense KKT system
/// [A_ff a_f; a_f^T 0] [x_f; lambda] = [b_f; 0] of the free dofs, solved by LU on the CPU.
void expect_constrained_solve(const gpu::HostBsrMatrix& host, const std::vector<char>& fixed,
    const std::vector<double>& b, const std::vector<double>& a, const char* name)
{
    const int n = host.size();
    std::vector<int> free_dofs;
    for (int k = 0; k < n; ++k)
        if (!fixed[size_t(k)])
            free_dofs.push_back(k);
    const int nf = int(free_dofs.size());
    Eigen::MatrixXd K = Eigen::MatrixXd::Zero(nf + 1, nf + 1);
    VectorXd rhs = VectorXd::Zero(nf + 1);
    for (int i = 0; i < nf; ++i) {
        for (int j = 0; j < nf; ++j)
            K(i, j) = host.coeff(free_dofs[size_t(i)], free_dofs[size_t(j)]);
        K(i, nf) = K(nf, i) = a[size_t(free_dofs[size_t(i)])];
        rhs[i] = b[size_t(free_dofs[size_t(i)])];
    }
    const VectorXd kkt = K.fullPivLu().solve(rhs);

    gpu::DeviceBsrMatrix A;
    A.upload(host);
    gpu::DeviceArray<double> d_a(a);
    gpu::DevicePCG pcg(gpu::PcgSettings { 1e-10, 10000 });
    pcg.set_fixed_dofs(fixed);
    pcg.set_constraint(d_a.data());
    std::vector<double> x;
    const gpu::PcgResult r = pcg.solve(A, b, x);
    EXPECT_TRUE(r.converged) << name;
    EXPECT_FALSE(r.breakdown) << name;
    EXPECT_LE(r.relative_residual, 3e-10) << name;
    double difference = 0, reference = 0, ax = 0, norm_a = 0, norm_x = 0;
    for (int i = 0; i < nf; ++i) {
        const size_t k = size_t(free_dofs[size_t(i)]);
        difference += std::pow(x[k] - kkt[i], 2);
        reference += kkt[i] * kkt[i];
        ax += a[k] * x[k];
        norm_a += a[k] * a[k];
        norm_x += x[k] * x[k];
    }
    for (int k = 0; k < n; ++k)
        if (fixed[size_t(k)])
            EXPECT_EQ(x[size_t(k)], 0.0) << name;
    difference = std::sqrt(difference / reference);
    EXPECT_LE(difference, 1e-7) << name;
    EXPECT_LE(std::abs(ax), 1e-12 * std::sqrt(norm_a * norm_x)) << name << ": off the hyperplane";
    std::printf("%s: %d free dofs, %d PCG iterations, relative residual %.2e, relative difference to the KKT "
                "solve %.2e, multiplier %.3e, a.x / |a||x| %.1e\n",
        name, nf, r.iterations, r.relative_residual, difference, kkt[nf], ax / std::sqrt(norm_a * norm_x));
    // The same bits again, and unconstrained again after set_constraint(nullptr).
    std::vector<double> again;
    const gpu::PcgResult second = pcg.solve(A, b, again);
    EXPECT_EQ(second.iterations, r.iterations) << name;
    EXPECT_EQ(again, x) << name;
    pcg.set_constraint(nullptr);
    EXPECT_EQ(pcg.constraint(), nullptr);
}

TEST(DevicePCG, SolvesOnAHyperplaneLikeTheKktSystem)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    const int dim = 3;
    const test::ElasticBox box = test::make_elastic_box(dim, { 5, 4, 3 }, -1, 0.15, 0.1, 37);
    gpu::DeviceElasticMesh m;
    m.upload(dim, box.rest_flat(), box.elements_flat(), box.models, box.mu_vector(), box.lambda_vector());
    const std::vector<double> x = box.x_vector();
    gpu::HostBsrMatrix host = m.hessian_bsr(x, true).download();
    std::vector<double> b = m.gradient(x);
    for (double& v : b)
        v = -v;
    const size_t n = b.size();
    std::vector<char> fixed(n, 0);
    for (Index v = 0; v < box.mesh.num_vertices(); ++v)
        if (box.mesh.rest_positions(v, 0) == 0)
            for (int i = 0; i < dim; ++i)
                fixed[size_t(v * dim + i)] = 1;
    // A dense direction on the free dofs, with the (positive definite) projected Hessian.
    std::mt19937 random(5);
    std::uniform_real_distribution<double> uniform(-1, 1);
    std::vector<double> a(n, 0.0);
    for (size_t k = 0; k < n; ++k)
        a[k] = fixed[k] ? 0.0 : uniform(random);
    expect_constrained_solve(host, fixed, b, a, "dense direction");

    // An indefinite matrix that is positive definite on the hyperplane: dof j's diagonal made negative
    // (e_j^T A e_j < 0), and a = e_j. Past a limit point the true Hessian is like this along the load.
    size_t j = 0;
    while (fixed[j])
        ++j;
    const int row = int(j) / dim, c = int(j) % dim;
    double row_sum = 0;
    for (int col = 0; col < host.size(); ++col)
        row_sum += std::abs(host.coeff(int(j), col));
    for (int slot = host.row_offsets[size_t(row)]; slot < host.row_offsets[size_t(row) + 1]; ++slot)
        if (host.col_indices[size_t(slot)] == row)
            host.values[size_t(slot) * dim * dim + size_t(c * dim + c)] -= 3 * row_sum;
    ASSERT_LT(host.coeff(int(j), int(j)), 0);
    std::vector<double> e(n, 0.0);
    e[j] = 1;
    expect_constrained_solve(host, fixed, b, e, "indefinite, positive definite on the hyperplane");

    // A direction that is zero is refused.
    gpu::DeviceBsrMatrix A;
    A.upload(host);
    gpu::DeviceArray<double> zero(std::vector<double>(n, 0.0));
    gpu::DevicePCG pcg;
    pcg.set_fixed_dofs(fixed);
    pcg.set_constraint(zero.data());
    std::vector<double> y;
    EXPECT_THROW(pcg.solve(A, b, y), std::invalid_argument);
}

} // namespace
