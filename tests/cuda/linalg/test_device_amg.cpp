// DeviceAmg (cuda/linalg/device_amg.hpp) on the GPU: its hierarchy against Eigen's products of the
// downloaded values (A_{l+1} = P^T A_l P; P - T a multiple of D^-1 A T, the multiple 4/(3 rho) with
// rho within the power iteration's reach of the true rho(D^-1 A)); as DevicePCG's preconditioner, the
// same solution as block-Jacobi in far fewer iterations, bitwise repeatable; a matrix small enough to be
// its own coarsest level solved in one iteration; a failed setup on a matrix that is not positive
// definite; with vertices fixed in some of their components only, the V-cycle as a matrix (applied to
// every unit vector) symmetric and positive definite on the free dofs. Skipped without a GPU.

#include "cuda/elastic/device_elastic_mesh.hpp"
#include "cuda/linalg/device_amg.hpp"
#include "cuda/linalg/device_pcg.hpp"
#include "tests/cuda/linalg/amg_test_utils.hpp"

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include <cstdio>

using namespace diffipc;

namespace {

/// A clamped neo-Hookean box on the device with a random right-hand side. The box is built in place:
/// its FE space refers to its mesh, so it must not be moved.
struct Problem {
    test::ElasticBox box;
    gpu::DeviceElasticMesh mesh;
    std::vector<char> fixed;
    std::vector<double> b;

    Problem(int dim, const std::vector<int>& cells, unsigned seed)
        : box(test::make_elastic_box(dim, cells, int(MaterialModel::NEO_HOOKEAN), 0.1, 0.1, seed))
        , fixed(test::clamped_face(box))
    {
        mesh.upload(dim, box.rest_flat(), box.elements_flat(), box.models, box.mu_vector(), box.lambda_vector());
        const VectorXd r = VectorXd::Random(box.mesh.num_dofs());
        b.assign(r.data(), r.data() + r.size());
    }
};

std::unique_ptr<Problem> make_problem(int dim, const std::vector<int>& cells, unsigned seed)
{
    return std::make_unique<Problem>(dim, cells, seed);
}

double relative_difference(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B) { return (A - B).norm() / B.norm(); }

/// A with its fixed dofs' rows and columns made identity ones.
Eigen::MatrixXd masked_dense(Eigen::MatrixXd A, const std::vector<char>& fixed)
{
    for (Index i = 0; i < A.rows(); ++i)
        if (fixed[size_t(i)]) {
            A.row(i).setZero();
            A.col(i).setZero();
            A(i, i) = 1;
        }
    return A;
}

} // namespace

TEST(DeviceAmg, HierarchyIsTheGalerkinHierarchyOfTheMatrix)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    const auto problem = make_problem(3, { 12, 5, 5 }, 3);
    const test::ElasticBox& box = problem->box;
    gpu::AmgPlanSettings settings;
    settings.max_coarsest_dofs = 60;
    const gpu::AmgPlan plan = gpu::plan_amg(3, test::box_pattern(box), box.x_vector(), problem->fixed, settings);
    ASSERT_EQ(plan.levels.size(), 2u);
    gpu::DeviceAmg amg(plan);
    const gpu::DeviceBsrMatrix& H = problem->mesh.hessian_bsr(box.x_vector(), true);
    ASSERT_TRUE(amg.setup(H));
    ASSERT_EQ(amg.num_levels(), 2);

    Eigen::MatrixXd A = masked_dense(Eigen::MatrixXd(test::cpu_hessian(box, box.x, 1.0, true)), problem->fixed);
    for (int l = 0; l < amg.num_levels(); ++l) {
        const gpu::AmgLevelPlan& level = plan.levels[size_t(l)];
        const int b = level.block, k = level.coarse_block, n = level.matrix.rows();
        const int na = level.num_aggregates();
        const Eigen::MatrixXd Al(test::block_matrix(level.matrix, b, b, n, amg.matrix_values(l)));
        EXPECT_LE(relative_difference(Al, A), 1e-12) << "level " << l << "'s matrix";
        const Eigen::MatrixXd P(test::block_matrix(level.prolongator, b, k, na, amg.prolongator_values(l)));
        const Eigen::MatrixXd T(test::tentative_matrix(level, na));
        const Eigen::MatrixXd Dinv(test::inverse_block_diagonal(SparseMatrixd(Al.sparseView()), b));
        // P - T = -omega D^-1 A T: fit omega, then the rest must vanish.
        const Eigen::MatrixXd X = Dinv * Al * T, Y = P - T;
        const double omega = -(X.cwiseProduct(Y)).sum() / X.squaredNorm();
        EXPECT_LE((Y + omega * X).norm(), 1e-12 * Y.norm()) << "level " << l << "'s prolongator";
        // omega = 4 / (3 rho_est), rho_est <= rho(D^-1 A) and not far below it.
        Eigen::MatrixXd Dhalf = Eigen::MatrixXd::Zero(Al.rows(), Al.cols());
        for (Index v = 0; v < Al.rows() / b; ++v) {
            Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> e(Dinv.block(v * b, v * b, b, b));
            Dhalf.block(v * b, v * b, b, b) = e.operatorSqrt();
        }
        const double rho = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Dhalf * Al * Dhalf).eigenvalues().maxCoeff();
        const double ratio = omega * rho / (4.0 / 3.0); // = rho / rho_est
        EXPECT_GE(ratio, 1.0 - 1e-9) << "the power iteration overestimated rho";
        EXPECT_LE(ratio, 1.25) << "the power iteration fell short of rho by more than 20%";
        const Eigen::MatrixXd Ac = P.transpose() * Al * P;
        const gpu::BlockPattern& coarse = l + 1 < amg.num_levels() ? plan.levels[size_t(l) + 1].matrix : plan.coarsest;
        Eigen::MatrixXd Ac_gpu(test::block_matrix(coarse, k, k, na, amg.matrix_values(l + 1)));
        // The coarsest level's stored matrix is masked (its inactive modes); mask the reference alike.
        const std::vector<char>& coarse_fixed
            = l + 1 < amg.num_levels() ? plan.levels[size_t(l) + 1].fixed : plan.coarsest_fixed;
        const Eigen::MatrixXd Ac_ref = masked_dense(Ac, coarse_fixed);
        EXPECT_LE(relative_difference(Ac_gpu, Ac_ref), 1e-12) << "level " << l + 1 << "'s Galerkin matrix";
        std::printf(
            "  level %d: %ld dofs, rho(D^-1 A) %.4f, estimated %.4f\n", l, long(Al.rows()), rho, 4.0 / (3.0 * omega));
        A = Ac_ref;
    }
}

namespace {

void compare_with_block_jacobi(int dim, const std::vector<int>& cells, bool project, int min_ratio)
{
    const auto problem = make_problem(dim, cells, 7);
    const test::ElasticBox& box = problem->box;
    const gpu::DeviceBsrMatrix& H = problem->mesh.hessian_bsr(box.x_vector(), project);
    gpu::DevicePCG pcg(gpu::PcgSettings { 1e-12, 20000 });
    pcg.set_fixed_dofs(problem->fixed);
    gpu::DeviceArray<double> d_b(problem->b), d_x(problem->b.size());
    const gpu::PcgResult bj = pcg.solve_device(H, d_b.data(), d_x.data());
    const std::vector<double> x_bj = d_x.download();

    gpu::DeviceAmg amg(gpu::plan_amg(dim, test::box_pattern(box), box.x_vector(), problem->fixed));
    ASSERT_TRUE(amg.setup(H));
    const gpu::PcgResult mg = pcg.solve_device(H, d_b.data(), d_x.data(), &amg);
    const std::vector<double> x_mg = d_x.download();
    ASSERT_TRUE(bj.converged);
    ASSERT_TRUE(mg.converged);
    EXPECT_LE(mg.relative_residual, 1e-11);
    const Eigen::Map<const VectorXd> a(x_bj.data(), Index(x_bj.size())), c(x_mg.data(), Index(x_mg.size()));
    const double agree = (a - c).norm() / a.norm();
    EXPECT_LE(agree, 1e-9);
    for (size_t k = 0; k < x_mg.size(); ++k)
        if (problem->fixed[k])
            ASSERT_EQ(x_mg[k], 0.0);
    EXPECT_LE(mg.iterations * min_ratio, bj.iterations) << "the multigrid should cut the iterations";
    std::printf("  %dD box, %d dofs, %s Hessian: %d levels + coarsest %d dofs; CG to 1e-12: block-Jacobi %d "
                "iterations, multigrid %d; solutions within %.1e\n",
        dim, H.size(), project ? "projected" : "true", amg.num_levels(), amg.level_size(amg.num_levels()),
        bj.iterations, mg.iterations, agree);

    // A second setup and solve give the same bits.
    ASSERT_TRUE(amg.setup(H));
    const gpu::PcgResult again = pcg.solve_device(H, d_b.data(), d_x.data(), &amg);
    EXPECT_EQ(again.iterations, mg.iterations);
    EXPECT_EQ(d_x.download(), x_mg);
}

} // namespace

TEST(DeviceAmg, CutsPcgIterations3D)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    compare_with_block_jacobi(3, { 32, 8, 8 }, true, 5);
    compare_with_block_jacobi(3, { 32, 8, 8 }, false, 5);
    compare_with_block_jacobi(3, { 48, 16, 16 }, false, 5);
}

TEST(DeviceAmg, CutsPcgIterations2D)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    compare_with_block_jacobi(2, { 120, 40 }, true, 4);
}

TEST(DeviceAmg, SmallMatrixIsSolvedExactly)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    const auto problem = make_problem(3, { 4, 3, 3 }, 5);
    const test::ElasticBox& box = problem->box;
    const gpu::AmgPlan plan = gpu::plan_amg(3, test::box_pattern(box), box.x_vector(), problem->fixed);
    ASSERT_TRUE(plan.levels.empty());
    gpu::DeviceAmg amg(plan);
    const gpu::DeviceBsrMatrix& H = problem->mesh.hessian_bsr(box.x_vector(), true);
    ASSERT_TRUE(amg.setup(H));
    gpu::DevicePCG pcg(gpu::PcgSettings { 1e-10, 100 });
    pcg.set_fixed_dofs(problem->fixed);
    gpu::DeviceArray<double> d_b(problem->b), d_x(problem->b.size());
    const gpu::PcgResult r = pcg.solve_device(H, d_b.data(), d_x.data(), &amg);
    EXPECT_TRUE(r.converged);
    EXPECT_EQ(r.iterations, 1) << "the dense inverse is the exact preconditioner";
    EXPECT_LE(r.relative_residual, 1e-12);
}

TEST(DeviceAmg, SetupFailsOnAMatrixThatIsNotPositiveDefinite)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    const auto problem = make_problem(2, { 4, 3 }, 5);
    const test::ElasticBox& box = problem->box;
    gpu::DeviceAmg amg(gpu::plan_amg(2, test::box_pattern(box), box.x_vector(), problem->fixed));
    gpu::HostBsrMatrix host = problem->mesh.hessian_bsr(box.x_vector(), true).download();
    for (double& v : host.values)
        v = -v;
    gpu::DeviceBsrMatrix negative;
    negative.upload(host);
    EXPECT_FALSE(amg.setup(negative));
    EXPECT_TRUE(amg.setup(problem->mesh.hessian_bsr(box.x_vector(), true))) << "a later setup succeeds again";
    gpu::DeviceBsrMatrix other;
    other.upload(gpu::HostBsrMatrix { 2, 1, { 0, 1 }, { 0 }, { 1, 0, 0, 1 } });
    EXPECT_THROW(amg.setup(other), std::invalid_argument);
}

TEST(DeviceAmg, VCycleIsSymmetricPositiveDefiniteWithPartlyFixedVertices)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    const auto problem = make_problem(3, { 12, 5, 5 }, 11);
    const test::ElasticBox& box = problem->box;
    // Besides the clamped face: rollers on the opposite face (y fixed only) and every fifth vertex's z,
    // so that blocks are partly masked and aggregates lose some of their rigid-body modes.
    const Index nv = box.mesh.num_vertices();
    const double x_max = box.mesh.rest_positions.col(0).maxCoeff();
    int partly = 0;
    for (Index v = 0; v < nv; ++v) {
        if (problem->fixed[size_t(3 * v)])
            continue;
        if (box.mesh.rest_positions(v, 0) == x_max) {
            problem->fixed[size_t(3 * v + 1)] = 1;
            ++partly;
        } else if (v % 5 == 0) {
            problem->fixed[size_t(3 * v + 2)] = 1;
            ++partly;
        }
    }
    gpu::AmgPlanSettings settings;
    settings.max_coarsest_dofs = 60;
    const gpu::AmgPlan plan = gpu::plan_amg(3, test::box_pattern(box), box.x_vector(), problem->fixed, settings);
    ASSERT_GE(plan.levels.size(), 2u);
    gpu::DeviceAmg amg(plan);
    const gpu::DeviceBsrMatrix& H = problem->mesh.hessian_bsr(box.x_vector(), true);
    ASSERT_TRUE(amg.setup(H));

    // M column by column: M e_j for every free dof j (the fixed ones are no input of apply()).
    const int n = H.size();
    Eigen::MatrixXd M = Eigen::MatrixXd::Zero(n, n);
    gpu::DeviceArray<double> e { size_t(n) }, z { size_t(n) };
    std::vector<double> unit(size_t(n), 0.0);
    for (int j = 0; j < n; ++j) {
        if (problem->fixed[size_t(j)])
            continue;
        unit[size_t(j)] = 1;
        e.upload(unit);
        unit[size_t(j)] = 0;
        amg.apply(e.data(), z.data());
        const std::vector<double> column = z.download();
        for (int i = 0; i < n; ++i)
            M(i, j) = column[size_t(i)];
    }
    std::vector<Index> free_dofs;
    for (int i = 0; i < n; ++i) {
        if (problem->fixed[size_t(i)])
            EXPECT_EQ(M.row(i).norm(), 0.0) << "fixed dof " << i << " of z is not 0";
        else
            free_dofs.push_back(i);
    }
    const Index nf = Index(free_dofs.size());
    Eigen::MatrixXd Mf(nf, nf);
    for (Index a = 0; a < nf; ++a)
        for (Index b = 0; b < nf; ++b)
            Mf(a, b) = M(free_dofs[size_t(a)], free_dofs[size_t(b)]);
    const double asymmetry = (Mf - Mf.transpose()).norm() / Mf.norm();
    EXPECT_LE(asymmetry, 1e-12) << "the V-cycle is not symmetric";
    const Eigen::VectorXd eigenvalues
        = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(0.5 * (Mf + Mf.transpose())).eigenvalues();
    EXPECT_GT(eigenvalues.minCoeff(), 0.0) << "the V-cycle is not positive definite";
    std::printf("  %ld free dofs (%d vertices fixed in one component), %d levels: |M - M^T| / |M| %.1e, "
                "eigenvalues of M in [%.3e, %.3e]\n",
        long(nf), partly, amg.num_levels(), asymmetry, eigenvalues.minCoeff(), eigenvalues.maxCoeff());

    // As PCG's preconditioner it still solves the system (block-Jacobi's solution, fewer iterations).
    gpu::DevicePCG pcg(gpu::PcgSettings { 1e-12, 20000 });
    pcg.set_fixed_dofs(problem->fixed);
    gpu::DeviceArray<double> d_b(problem->b), d_x(problem->b.size());
    const gpu::PcgResult bj = pcg.solve_device(H, d_b.data(), d_x.data());
    const std::vector<double> x_bj = d_x.download();
    const gpu::PcgResult mg = pcg.solve_device(H, d_b.data(), d_x.data(), &amg);
    const std::vector<double> x_mg = d_x.download();
    ASSERT_TRUE(bj.converged);
    ASSERT_TRUE(mg.converged);
    const Eigen::Map<const VectorXd> a(x_bj.data(), Index(n)), c(x_mg.data(), Index(n));
    EXPECT_LE((a - c).norm() / a.norm(), 1e-9);
    EXPECT_LT(mg.iterations, bj.iterations);
    std::printf("  PCG to 1e-12: block-Jacobi %d iterations, multigrid %d\n", bj.iterations, mg.iterations);
}
