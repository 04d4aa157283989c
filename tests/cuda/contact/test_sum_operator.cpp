// SumOperator (cuda/contact/sum_operator.hpp): the Newton matrix of a contact scene as the elastic
// BSR matrix plus the contact BSR matrix, its product, its block diagonal, the assembled sum on the
// union pattern, and a DevicePCG solve with that sum. Skipped without a GPU.

#include "cuda/contact/device_barrier.hpp"
#include "cuda/contact/sum_operator.hpp"
#include "cuda/elastic/device_elastic_mesh.hpp"
#include "cuda/linalg/device_pcg.hpp"
#include "tests/cuda/contact/contact_test_utils.hpp"

#include "forward/materials/material.hpp"

using namespace diffipc;

namespace {

/// The scene's elastic Hessian (projected, neo-Hookean E = 1e5, nu = 0.3) at x, plus `mass` on the
/// diagonal (so that the sum is positive definite), as a device BSR matrix.
gpu::DeviceBsrMatrix elastic_matrix(const test::ContactScene& scene, double mass)
{
    const Mesh& mesh = scene.sim->mesh();
    const int dim = mesh.dim, n = dim + 1;
    std::vector<int> elements;
    for (Index e = 0; e < mesh.num_elements(); ++e)
        for (int a = 0; a < n; ++a)
            elements.push_back(int(mesh.elements(e, a)));
    const size_t ne = size_t(mesh.num_elements());
    const double E = 1e5, nu = 0.3;
    gpu::DeviceElasticMesh elastic;
    elastic.upload(dim, scene.rest_vector(), elements, std::vector<MaterialModel>(ne, MaterialModel::NEO_HOOKEAN),
        std::vector<double>(ne, E / (2 * (1 + nu))), std::vector<double>(ne, E * nu / ((1 + nu) * (1 - 2 * nu))));
    gpu::HostBsrMatrix A = elastic.hessian_bsr(scene.x_vector(), true).download();
    for (int r = 0; r < A.num_block_rows; ++r)
        for (int k = A.row_offsets[size_t(r)]; k < A.row_offsets[size_t(r) + 1]; ++k)
            if (A.col_indices[size_t(k)] == r)
                for (int i = 0; i < dim; ++i)
                    A.values[size_t(k * dim * dim + i * dim + i)] += mass;
    gpu::DeviceBsrMatrix d;
    d.upload(A);
    return d;
}

} // namespace

TEST(ContactSumOperator, ProductDiagonalAndSumEqualTheHostSum)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    const test::ContactScene scene = test::boxes_on_plane(4, 0.3, 5e-5, { { "dhat", 1e-3 }, { "kappa", 3.0 } });
    const gpu::DeviceBsrMatrix A = elastic_matrix(scene, 1e3);
    gpu::DeviceBarrier barrier;
    barrier.upload(scene.dim(), scene.rest_vector(), scene.plane_normals());
    // kappa 1e9: contact blocks of the size of the elastic ones (so that the sums test something).
    barrier.set_settings({ 1e9, 1e-3, 0.0 });
    barrier.set_pairs(scene.pairs());
    const gpu::DeviceBsrMatrix& C = barrier.hessian_bsr(scene.x_vector(), true);
    ASSERT_GT(C.num_blocks(), 0);

    gpu::SumOperator op;
    op.bind(A, C);
    const SparseMatrixd As = test::to_sparse(A.download()), Cs = test::to_sparse(C.download());
    const SparseMatrixd sum = As + Cs;
    // The assembled sum on the union pattern is the entrywise sum, exactly.
    gpu::DeviceBsrMatrix S = op.make_sum_matrix();
    op.assemble_sum(S);
    const gpu::HostBsrMatrix S_host = S.download();
    EXPECT_EQ(test::relative_difference(test::to_sparse(S_host), sum), 0.0);
    EXPECT_EQ(S.num_blocks(), int(op.sum_col_indices().size()));
    EXPECT_GT(S.num_blocks(), A.num_blocks()); // contact couples vertices the elastic pattern does not

    // Products, without and with fixed dofs (the obstacle's vertex).
    const VectorXd x = test::random_vector(Eigen::Index(A.size()), 5);
    const std::vector<double> xv(x.data(), x.data() + x.size());
    const VectorXd y_ref = sum * x;
    const std::vector<double> y = op.multiply(xv);
    EXPECT_LE((test::as_eigen(y) - y_ref).lpNorm<Eigen::Infinity>(), 1e-12 * y_ref.lpNorm<Eigen::Infinity>());
    std::vector<unsigned char> fixed(size_t(A.size()), 0);
    for (Index v = scene.sim->scene().body_vertices; v < scene.sim->mesh().num_vertices(); ++v)
        for (int i = 0; i < 3; ++i)
            fixed[size_t(v * 3 + i)] = 1;
    gpu::DeviceArray<double> d_x(xv), d_y(xv.size()), d_ys(xv.size());
    gpu::DeviceArray<unsigned char> d_fixed(fixed);
    op.multiply(d_x.data(), d_y.data(), d_fixed.data());
    S.multiply(d_x.data(), d_ys.data(), d_fixed.data());
    const std::vector<double> yf = d_y.download(), ysf = d_ys.download();
    EXPECT_LE((test::as_eigen(yf) - test::as_eigen(ysf)).lpNorm<Eigen::Infinity>(),
        1e-12 * test::as_eigen(ysf).lpNorm<Eigen::Infinity>());
    for (size_t k = 0; k < fixed.size(); ++k)
        if (fixed[k])
            EXPECT_EQ(yf[k], 0.0);

    // Block diagonal.
    const int b = 3;
    gpu::DeviceArray<double> d_diag(size_t(A.num_block_rows() * b * b));
    op.diagonal_blocks(d_diag.data());
    const std::vector<double> diag = d_diag.download();
    for (int r = 0; r < A.num_block_rows(); ++r)
        for (int i = 0; i < b; ++i)
            for (int j = 0; j < b; ++j)
                ASSERT_EQ(diag[size_t(r * b * b + i * b + j)], sum.coeff(r * b + i, r * b + j)) << r;

    // DevicePCG solves with the assembled sum as it is.
    gpu::DevicePCG pcg(gpu::PcgSettings { 1e-10, 5000 });
    std::vector<char> fixed_chars(fixed.begin(), fixed.end());
    pcg.set_fixed_dofs(fixed_chars);
    std::vector<double> u;
    const gpu::PcgResult r = pcg.solve(S, xv, u);
    EXPECT_TRUE(r.converged);
    VectorXd residual = x - sum * test::as_eigen(u);
    VectorXd rhs = x;
    for (size_t k = 0; k < fixed.size(); ++k)
        if (fixed[k])
            residual[Eigen::Index(k)] = rhs[Eigen::Index(k)] = 0;
    // With the fixed dofs' columns dropped (u is 0 there).
    EXPECT_LE(residual.norm(), 1e-8 * rhs.norm());
    std::printf("  %d elastic blocks + %d contact blocks -> %d blocks; PCG %d iterations, residual %.1e\n",
        A.num_blocks(), C.num_blocks(), S.num_blocks(), r.iterations, r.relative_residual);
}
