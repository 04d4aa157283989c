// A periodic cell's Newton matrix in its reduced unknowns on the device (cuda/periodic/reduced_operator.hpp),
// P^T A P with A the projected elastic Hessian of a deformed box, against the CPU's P^T H P (PeriodicMap's
// sparse P and the CPU potential's Hessian): products, the preconditioner's diagonal blocks, and a PCG
// solve with a pinned class and fixed macro entries against a direct solve. Skipped without a GPU.

#include "cuda/elastic/device_elastic_mesh.hpp"
#include "cuda/linalg/device_pcg.hpp"
#include "cuda/periodic/reduced_operator.hpp"
#include "forward/periodic/periodic_map.hpp"
#include "tests/cuda/elastic_test_utils.hpp"
#include "tests/cuda/periodic/periodic_test_utils.hpp"
#include "tests/forward/test_utils.hpp"

#include <Eigen/Cholesky>
#include <gtest/gtest.h>

#include <cstdio>

using namespace diffipc;

TEST(ReducedOperator, ProductsBlocksAndSolvesEqualTheCpus)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    for (int d : { 2, 3 }) {
        SCOPED_TRACE(d);
        const test::ElasticBox box = test::make_elastic_box(
            d, d == 2 ? std::vector<int> { 6, 4 } : std::vector<int> { 3, 3, 2 }, -1, 0.15, 0.1, 31 + unsigned(d));
        test::BoxCell cell(box.mesh);
        const PeriodicPairing& pairing = cell.pairing;
        const PeriodicMap& map = *cell.map;
        const int nq = int(map.num_reduced()), classes = int(pairing.num_classes());

        gpu::DeviceElasticMesh mesh;
        mesh.upload(d, box.rest_flat(), box.elements_flat(), box.models, box.mu_vector(), box.lambda_vector());
        const gpu::DeviceBsrMatrix& H = mesh.hessian_bsr(box.x_vector(), true);
        gpu::ReducedOperator R;
        R.bind(H, cell.device(box.rest_flat()));
        ASSERT_EQ(R.size(), nq);

        const SparseMatrixd Hc = test::cpu_hessian(box, box.x, 1.0, true);
        const SparseMatrixd Rc = map.matrix().transpose() * Hc * map.matrix();
        const MatrixXd dense = MatrixXd(Rc);

        // Products.
        const VectorXd v = test::random_vector(nq, 3);
        const std::vector<double> y = R.multiply(std::vector<double>(v.data(), v.data() + nq));
        const VectorXd expected = Rc * v;
        const double product_error = (Eigen::Map<const VectorXd>(y.data(), nq) - expected).lpNorm<Eigen::Infinity>()
            / expected.lpNorm<Eigen::Infinity>();
        EXPECT_LE(product_error, 1e-12);

        // Diagonal blocks: the macro rows' exact, the classes' the sum of their vertices' blocks.
        gpu::DeviceArray<double> blocks { size_t(R.num_block_rows() * d * d) };
        R.diagonal_blocks(blocks.data());
        const std::vector<double> b = blocks.download();
        double macro_error = 0, class_error = 0, scale = dense.cwiseAbs().maxCoeff();
        int exact_classes = 0;
        for (int c = 0; c < classes; ++c) {
            MatrixXd sum = MatrixXd::Zero(d, d);
            for (Index u = 0; u < box.mesh.num_vertices(); ++u)
                if (pairing.vertex_class[u] == c)
                    sum += MatrixXd(Hc.block(u * d, u * d, d, d));
            for (int i = 0; i < d; ++i)
                for (int j = 0; j < d; ++j)
                    class_error = std::max(class_error, std::abs(b[size_t((c * d + i) * d + j)] - sum(i, j)));
            exact_classes += (dense.block(c * d, c * d, d, d) - sum).cwiseAbs().maxCoeff() <= 1e-12 * scale;
        }
        for (int i = 0; i < d; ++i)
            for (int j = 0; j < d; ++j)
                for (int k = 0; k < d; ++k)
                    macro_error = std::max(macro_error,
                        std::abs(b[size_t(((classes + i) * d + j) * d + k)]
                            - dense(map.macro_dof(i, j), map.macro_dof(i, k))));
        EXPECT_LE(class_error, 1e-12 * scale);
        EXPECT_LE(macro_error, 1e-12 * scale);

        // A solve with the CPU's constraints: the class of vertex 0 pinned, G's off-diagonal entries fixed.
        std::vector<char> fixed(size_t(nq), 0);
        for (int i = 0; i < d; ++i) {
            fixed[size_t(map.fluctuation_dof(pairing.vertex_class[0], i))] = 1;
            for (int j = 0; j < d; ++j)
                fixed[size_t(map.macro_dof(i, j))] = i != j;
        }
        VectorXd rhs = test::random_vector(nq, 9);
        for (int k = 0; k < nq; ++k)
            if (fixed[size_t(k)])
                rhs[k] = 0;
        gpu::DevicePCG pcg(gpu::PcgSettings { 1e-12, 20000 });
        pcg.set_fixed_dofs(fixed);
        gpu::DeviceArray<double> db(std::vector<double>(rhs.data(), rhs.data() + nq));
        gpu::DeviceArray<double> dx { size_t(nq) };
        const gpu::PcgResult r = pcg.solve_device(R, db.data(), dx.data());
        EXPECT_TRUE(r.converged);
        const std::vector<double> x = dx.download();
        MatrixXd A = dense;
        for (int k = 0; k < nq; ++k)
            if (fixed[size_t(k)]) {
                A.row(k).setZero();
                A.col(k).setZero();
                A(k, k) = 1;
            }
        const VectorXd x_cpu = A.ldlt().solve(rhs);
        const double solve_error = (Eigen::Map<const VectorXd>(x.data(), nq) - x_cpu).lpNorm<Eigen::Infinity>()
            / x_cpu.lpNorm<Eigen::Infinity>();
        EXPECT_LE(solve_error, 1e-7);
        std::printf("  %dD cell, %d classes, %d reduced unknowns: product %.1e, class blocks %.1e (%d of %d exact), "
                    "macro blocks %.1e; PCG %d iterations, solution within %.1e of a direct solve\n",
            d, classes, nq, product_error, class_error / scale, exact_classes, classes, macro_error / scale,
            r.iterations, solve_error);
    }
}

TEST(ReducedOperator, OperatorSumAddsProductsAndBlocks)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    // A periodic cell with contact sums P^T H P and P_s^T C P_s (OperatorSum). Here the second operator is
    // P^T H2 P with H2 the Hessian of the same box at twice its Lame parameters, 2 H exactly (the
    // Hessian is linear in them): the sum is 3 P^T H P, which neither A + A nor B + B gives.
    const int d = 3;
    const test::ElasticBox box = test::make_elastic_box(d, { 3, 3, 2 }, -1, 0.15, 0.1, 41);
    test::BoxCell cell(box.mesh);
    gpu::DeviceElasticMesh mesh, stiffer;
    mesh.upload(d, box.rest_flat(), box.elements_flat(), box.models, box.mu_vector(), box.lambda_vector());
    std::vector<double> mu2 = box.mu_vector(), lambda2 = box.lambda_vector();
    for (double& v : mu2)
        v *= 2;
    for (double& v : lambda2)
        v *= 2;
    stiffer.upload(d, box.rest_flat(), box.elements_flat(), box.models, mu2, lambda2);
    gpu::DevicePeriodicMap& map = cell.device(box.rest_flat());
    gpu::ReducedOperator A, B;
    A.bind(mesh.hessian_bsr(box.x_vector(), true), map);
    B.bind(stiffer.hessian_bsr(box.x_vector(), true), map);
    gpu::OperatorSum sum;
    sum.bind(A, B);
    const int nq = A.size();
    ASSERT_EQ(sum.size(), nq);

    const SparseMatrixd Hc = test::cpu_hessian(box, box.x, 1.0, true);
    const SparseMatrixd Rc = cell.map->matrix().transpose() * Hc * cell.map->matrix();
    const VectorXd v = test::random_vector(nq, 5);
    const std::vector<double> y = sum.multiply(std::vector<double>(v.data(), v.data() + nq));
    const VectorXd expected = 3 * (Rc * v);
    const double product_error = (Eigen::Map<const VectorXd>(y.data(), nq) - expected).lpNorm<Eigen::Infinity>()
        / expected.lpNorm<Eigen::Infinity>();
    EXPECT_LE(product_error, 1e-12);

    const size_t count = size_t(A.num_block_rows() * d * d);
    gpu::DeviceArray<double> a_blocks { count }, s_blocks { count };
    A.diagonal_blocks(a_blocks.data());
    sum.diagonal_blocks(s_blocks.data());
    const std::vector<double> ab = a_blocks.download(), sb = s_blocks.download();
    double block_error = 0, scale = 0;
    for (size_t k = 0; k < count; ++k) {
        block_error = std::max(block_error, std::abs(sb[k] - 3 * ab[k]));
        scale = std::max(scale, std::abs(ab[k]));
    }
    EXPECT_LE(block_error, 1e-12 * scale);
    std::printf("  OperatorSum of two reduced operators (%d unknowns): product %.1e, blocks %.1e relative\n", nq,
        product_error, block_error / scale);

    // Operators of different shapes are refused.
    gpu::OperatorSum wrong;
    EXPECT_THROW(wrong.bind(A, mesh.hessian_bsr(box.x_vector(), true)), std::invalid_argument);
}
