// DeviceElasticMesh (cuda/elastic/device_elastic_mesh.hpp) on the GPU against the CPU
// ElasticPotential: energy, gradient, assembled BSR Hessian (true and projected), determinism.
// Skipped without a GPU. DISABLED_TimingsOfA200kTetBox prints timings (run it with
// --gtest_also_run_disabled_tests).

#include "cuda/elastic/device_elastic_mesh.hpp"
#include "cuda/linalg/device_pcg.hpp"
#include "tests/cuda/elastic_test_utils.hpp"

#include <cuda_runtime_api.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

using namespace diffipc;

namespace {

gpu::DeviceElasticMesh upload(const test::ElasticBox& box)
{
    gpu::DeviceElasticMesh m;
    m.upload(box.mesh.dim, box.rest_flat(), box.elements_flat(), box.models, box.mu_vector(), box.lambda_vector());
    return m;
}

void compare_with_cpu(int dim, const std::vector<int>& cells)
{
    // Random models and parameters per element, a stretch and a random deformation.
    const test::ElasticBox box = test::make_elastic_box(dim, cells, -1, 0.15, 0.1, 21 + unsigned(dim));
    const gpu::DeviceElasticMesh gpu_mesh = upload(box);
    ASSERT_EQ(gpu_mesh.num_dofs(), box.mesh.num_dofs());
    const std::vector<double> x = box.x_vector();
    const double weight = 0.7;

    const double e_cpu = box.potential->value(box.x), e_gpu = gpu_mesh.energy(x);
    EXPECT_LE(std::abs(e_gpu - e_cpu), 1e-12 * box.potential->value_scale(box.x)) << e_gpu << " vs " << e_cpu;

    VectorXd g_cpu = VectorXd::Zero(box.mesh.num_dofs());
    box.potential->add_gradient(box.x, weight, g_cpu);
    const std::vector<double> g = gpu_mesh.gradient(x, weight);
    const Eigen::Map<const VectorXd> g_gpu(g.data(), Index(g.size()));
    EXPECT_LE((g_gpu - g_cpu).norm(), 1e-12 * g_cpu.norm());

    for (bool project : { false, true }) {
        const SparseMatrixd H_cpu = test::cpu_hessian(box, box.x, weight, project);
        const gpu::HostBsrMatrix H = gpu_mesh.hessian_bsr(x, project, weight).download();
        const SparseMatrixd H_gpu = test::to_sparse(H);
        EXPECT_LE((H_gpu - H_cpu).norm(), 1e-12 * H_cpu.norm()) << "project " << project;
        // The BSR matrix-vector product against the CPU's.
        const std::vector<double> y = gpu_mesh.hessian_bsr(x, project, weight).multiply(x);
        const VectorXd y_cpu = H_cpu * box.x;
        EXPECT_LE((Eigen::Map<const VectorXd>(y.data(), Index(y.size())) - y_cpu).norm(), 1e-12 * y_cpu.norm());
    }
    std::printf("dim %d, %d elements: GPU vs CPU energy %.3e, relative gradient difference %.2e\n", dim,
        gpu_mesh.num_elements(), e_gpu - e_cpu, (g_gpu - g_cpu).norm() / g_cpu.norm());
}

TEST(DeviceElasticMesh, EnergyGradientHessianEqualCpu3D)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    compare_with_cpu(3, { 5, 4, 3 }); // 360 tetrahedra
}

TEST(DeviceElasticMesh, EnergyGradientHessianEqualCpu2D)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    compare_with_cpu(2, { 12, 9 });
}

TEST(DeviceElasticMesh, EvaluationsAreBitwiseRepeatable)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    const test::ElasticBox box = test::make_elastic_box(3, { 6, 5, 4 }, -1, 0.15, 0.1, 5);
    const gpu::DeviceElasticMesh m = upload(box);
    const std::vector<double> x = box.x_vector();
    const double e0 = m.energy(x), e1 = m.energy(x);
    EXPECT_EQ(std::memcmp(&e0, &e1, sizeof(double)), 0);
    EXPECT_EQ(m.gradient(x), m.gradient(x));
    const std::vector<double> h0 = m.hessian_bsr(x, true).download().values;
    const std::vector<double> h1 = m.hessian_bsr(x, true).download().values;
    EXPECT_EQ(h0, h1);
    // Another object on the same data gives the same bits too.
    const gpu::DeviceElasticMesh other = upload(box);
    EXPECT_EQ(other.gradient(x), m.gradient(x));
    EXPECT_EQ(other.hessian_bsr(x, true).download().values, h0);
}

TEST(DeviceElasticMesh, InvertedNeoHookeanElementGivesInfiniteEnergy)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    test::ElasticBox box = test::make_elastic_box(2, { 3, 3 }, int(MaterialModel::NEO_HOOKEAN), 0.0, 0.0, 1);
    const gpu::DeviceElasticMesh m = upload(box);
    std::vector<double> x = box.x_vector();
    EXPECT_NEAR(m.energy(x), 0.0, 1e-12);
    Index interior = 0; // the vertex at (0.1, 0.1), pushed through its neighbours
    for (Index v = 0; v < box.mesh.num_vertices(); ++v)
        if ((box.mesh.rest_positions.row(v) - Eigen::RowVector2d(0.1, 0.1)).norm() < 1e-9)
            interior = v;
    x[size_t(2 * interior)] += 0.5;
    x[size_t(2 * interior + 1)] += 0.5;
    EXPECT_TRUE(std::isinf(box.potential->value(Eigen::Map<VectorXd>(x.data(), Index(x.size())))));
    EXPECT_TRUE(std::isinf(m.energy(x)) && m.energy(x) > 0);
}

TEST(DeviceElasticMesh, RejectsBadInput)
{
    gpu::DeviceElasticMesh m;
    // Checked on the host before any GPU work.
    EXPECT_THROW(m.upload(4, {}, {}, {}, {}, {}), std::invalid_argument);
    EXPECT_THROW(
        m.upload(2, { 0, 0, 1, 0, 0, 1 }, { 0, 1, 2 }, { MaterialModel(7) }, { 1 }, { 1 }), std::invalid_argument);
    EXPECT_THROW(
        m.upload(2, { 0, 0, 1, 0, 2, 0 }, { 0, 1, 2 }, { MaterialModel::LINEAR }, { 1 }, { 1 }), std::invalid_argument);
    EXPECT_THROW(
        m.upload(2, { 0, 0, 1, 0, 0, 1 }, { 0, 1, 3 }, { MaterialModel::LINEAR }, { 1 }, { 1 }), std::invalid_argument);
}

/// Seconds of GPU work between two events around `work`, averaged over `repeats`.
template <typename Work> double gpu_seconds(int repeats, Work work)
{
    cudaEvent_t start, stop;
    cudaEventCreate(&start);
    cudaEventCreate(&stop);
    work(); // warm-up (allocations on first use)
    cudaDeviceSynchronize();
    cudaEventRecord(start);
    for (int k = 0; k < repeats; ++k)
        work();
    cudaEventRecord(stop);
    cudaEventSynchronize(stop);
    float ms = 0;
    cudaEventElapsedTime(&ms, start, stop);
    cudaEventDestroy(start);
    cudaEventDestroy(stop);
    return ms / 1000.0 / repeats;
}

template <typename Work> double cpu_seconds(int repeats, Work work)
{
    work();
    const auto t0 = std::chrono::steady_clock::now();
    for (int k = 0; k < repeats; ++k)
        work();
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / repeats;
}

// Prints (asserts nothing about speed): GPU energy + gradient + projected Hessian assembly, and a
// block-Jacobi PCG solve of the Newton system with the bottom face fixed, on a box of 32^3 cubes
// (196,608 tetrahedra, 107,811 dofs), and the CPU ElasticPotential's time on the same mesh.
TEST(DeviceElasticMesh, DISABLED_TimingsOfA200kTetBox)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    std::printf("device: %s\n", gpu::cuda_device_description().c_str());
    const test::ElasticBox box
        = test::make_elastic_box(3, { 32, 32, 32 }, int(MaterialModel::NEO_HOOKEAN), 0.05, 0.05, 2, false);
    const gpu::DeviceElasticMesh m = upload(box);
    const std::vector<double> x = box.x_vector();
    gpu::DeviceArray<double> d_x(x), d_g(x.size()), d_p(x.size());
    gpu::DeviceBsrMatrix H = m.make_hessian_matrix();
    std::printf("mesh: %d tetrahedra, %d vertices, %d dofs, %d BSR blocks\n", m.num_elements(), m.num_vertices(),
        m.num_dofs(), H.num_blocks());

    double energy = 0;
    const double t_energy = gpu_seconds(10, [&] { energy = m.energy_device(d_x.data()); });
    const double t_gradient = gpu_seconds(10, [&] {
        d_g.set_zero();
        m.add_gradient_device(d_x.data(), 1.0, d_g.data());
    });
    const double t_hessian = gpu_seconds(5, [&] {
        H.set_zero();
        m.add_hessian_device(d_x.data(), 1.0, true, H);
    });
    const double t_hessian_true = gpu_seconds(5, [&] {
        H.set_zero();
        m.add_hessian_device(d_x.data(), 1.0, false, H);
    });
    std::printf("GPU: energy %.3f ms, gradient %.3f ms, projected Hessian assembly %.3f ms (unprojected %.3f ms); "
                "energy + gradient + projected Hessian %.3f ms\n",
        1e3 * t_energy, 1e3 * t_gradient, 1e3 * t_hessian, 1e3 * t_hessian_true,
        1e3 * (t_energy + t_gradient + t_hessian));

    // Newton system H p = -g with the bottom face (z = 0) fixed.
    H.set_zero();
    m.add_hessian_device(d_x.data(), 1.0, true, H);
    std::vector<double> g = m.gradient(x);
    std::vector<char> fixed(x.size(), 0);
    for (Index v = 0; v < box.mesh.num_vertices(); ++v)
        if (box.mesh.rest_positions(v, 2) == 0)
            for (int i = 0; i < 3; ++i)
                fixed[size_t(v * 3 + i)] = 1;
    for (double& gi : g)
        gi = -gi;
    gpu::DeviceArray<double> d_b(g);
    for (double tol : { 1e-4, 1e-10 }) {
        gpu::DevicePCG pcg(gpu::PcgSettings { tol, 20000 });
        pcg.set_fixed_dofs(fixed);
        gpu::PcgResult r;
        const double t_pcg = gpu_seconds(1, [&] { r = pcg.solve_device(H, d_b.data(), d_p.data()); });
        std::printf("GPU PCG (block Jacobi), tolerance %.0e: %d iterations, relative residual %.2e, %.1f ms "
                    "(%.3f ms per iteration)\n",
            tol, r.iterations, r.relative_residual, 1e3 * t_pcg, 1e3 * t_pcg / std::max(1, r.iterations));
    }

    // The CPU potential on the same mesh (all threads of this machine).
    SparseAssembler assembler;
    assembler.build(3, box.mesh.num_vertices(), box.mesh.elements);
    VectorXd g_cpu(box.mesh.num_dofs());
    double e_cpu = 0;
    const double c_energy = cpu_seconds(3, [&] { e_cpu = box.potential->value(box.x); });
    const double c_gradient = cpu_seconds(3, [&] {
        g_cpu.setZero();
        box.potential->add_gradient(box.x, 1.0, g_cpu);
    });
    const double c_hessian = cpu_seconds(2, [&] {
        assembler.set_zero();
        box.potential->add_hessian(box.x, 1.0, true, assembler);
    });
    std::printf("CPU ElasticPotential: energy %.1f ms, gradient %.1f ms, projected Hessian assembly %.1f ms; "
                "total %.1f ms (GPU speed-up %.1fx)\n",
        1e3 * c_energy, 1e3 * c_gradient, 1e3 * c_hessian, 1e3 * (c_energy + c_gradient + c_hessian),
        (c_energy + c_gradient + c_hessian) / (t_energy + t_gradient + t_hessian));
    std::printf("energy GPU %.15e, CPU %.15e\n", energy, e_cpu);
}

} // namespace
