// A periodic cell's Newton solve on the device (DeviceNewton::set_periodic / solve_periodic) against the
// CPU's (NewtonSolver on PeriodicPotential, as PeriodicCell::solve runs it): a heterogeneous cell (random
// materials and Lame parameters per element) compressed by a prescribed macro gradient component with
// the other diagonal components free and the shear held, the class of the lower corner pinned; 2D and
// 3D. Compared: the reduced unknowns q (fluctuations and L G) relative to the cell's size, and the CPU's
// own reduced residual at the GPU's q. Skipped without a GPU.

#include "cuda/elastic/device_elastic_mesh.hpp"
#include "cuda/periodic/device_periodic_map.hpp"
#include "cuda/solver/device_newton.hpp"
#include "forward/periodic/periodic_potential.hpp"
#include "forward/scene/scene.hpp"
#include "forward/solver/linear_solver.hpp"
#include "forward/solver/newton.hpp"
#include "tests/cuda/elastic_test_utils.hpp"
#include "tests/cuda/periodic/periodic_test_utils.hpp"

#include <gtest/gtest.h>

#include <cstdio>

using namespace diffipc;

TEST(DevicePeriodicNewton, HeterogeneousCellUnderCompressionAsOnTheCpu)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    constexpr double TOLERANCE = 1e-10;
    for (int d : { 2, 3 }) {
        SCOPED_TRACE(d);
        // make_elastic_box's materials (random models and Lame parameters per element); its deformed state is
        // not used: both solves start from rest, q = 0.
        const test::ElasticBox box = test::make_elastic_box(
            d, d == 2 ? std::vector<int> { 6, 5 } : std::vector<int> { 3, 3, 3 }, -1, 0, 0, 41 + unsigned(d));
        test::BoxCell cell(box.mesh);
        const PeriodicPairing& pairing = cell.pairing;
        const PeriodicMap& map = *cell.map;
        const double L = cell.length;
        const Index nq = map.num_reduced();

        // q's constraints: the lower corner's class, G(0, 0) = -0.1 (10% compression), the shear entries 0.
        std::vector<char> fixed(size_t(nq), 0);
        VectorXd target = VectorXd::Zero(nq);
        for (int i = 0; i < d; ++i) {
            fixed[size_t(map.fluctuation_dof(pairing.vertex_class[0], i))] = 1;
            for (int j = 0; j < d; ++j)
                fixed[size_t(map.macro_dof(i, j))] = i != j || (i == 0 && j == 0);
        }
        target[map.macro_dof(0, 0)] = L * -0.1;
        const double force_scale = 1e4 * std::pow(0.1, d - 1), step_scale = L;

        // CPU.
        Problem full;
        full.add(box.potential.get(), 1.0);
        SparseAssembler full_assembler, reduced_assembler;
        full_assembler.build(d, box.mesh.num_vertices(), box.mesh.elements);
        PeriodicPotential periodic(full, full_assembler, map);
        Problem reduced;
        reduced.add(&periodic, 1.0);
        reduced_assembler.build(d, pairing.num_classes() + d, periodic_elements(box.mesh, pairing), false);
        LinearSolver linear(LinearSolverType::CHOLMOD);
        NewtonSettings cpu_settings;
        cpu_settings.residual_tolerance = TOLERANCE;
        const NewtonSolver newton(reduced, reduced_assembler, linear, cpu_settings);
        VectorXd q_cpu = VectorXd::Zero(nq);
        const NewtonResult rc = newton.solve(q_cpu, target, fixed, force_scale, step_scale);
        ASSERT_EQ(rc.status, StepStatus::CONVERGED);

        // GPU.
        gpu::DeviceElasticMesh mesh;
        mesh.upload(d, box.rest_flat(), box.elements_flat(), box.models, box.mu_vector(), box.lambda_vector());
        gpu::DeviceNewton solver(mesh, {});
        solver.set_material_scale(box.models, box.mu_vector());
        solver.set_periodic(&cell.device(box.rest_flat()), fixed);
        gpu::DeviceNewtonSettings settings;
        settings.residual_tolerance = TOLERANCE;
        std::vector<double> q(size_t(nq), 0.0);
        const gpu::DeviceNewtonResult rg
            = solver.solve_periodic(q, std::vector<double>(target.data(), target.data() + nq), {}, 1.0,
                std::vector<double>(size_t(box.mesh.num_vertices() * d), 0.0), force_scale, step_scale, settings);
        ASSERT_EQ(rg.status, gpu::DeviceStepStatus::CONVERGED);

        const Eigen::Map<const VectorXd> q_gpu(q.data(), nq);
        for (int k = 0; k < nq; ++k)
            if (fixed[size_t(k)])
                EXPECT_EQ(q_gpu[k], target[k]) << "constrained entry " << k;
        const double difference = (q_gpu - q_cpu).lpNorm<Eigen::Infinity>() / L;
        EXPECT_LE(difference, 1e-8);
        // The CPU's reduced residual at the GPU's q.
        VectorXd g = VectorXd::Zero(nq);
        periodic.add_gradient(q_gpu, 1.0, g);
        double residual = 0;
        for (int k = 0; k < nq; ++k)
            if (!fixed[size_t(k)])
                residual = std::max(residual, std::abs(g[k]));
        residual /= force_scale;
        EXPECT_LE(residual, 10 * TOLERANCE);
        // The free macro components moved: the cell widened laterally under the compression.
        EXPECT_GT(q_gpu[map.macro_dof(1, 1)], 0);
        std::printf("  %dD cell, %d classes, %ld reduced unknowns: CPU %d Newton iterations, GPU %d (%d PCG); q within "
                    "%.1e of the size; CPU residual at the GPU's q %.1e; G(1,1) = %.4f\n",
            d, int(pairing.num_classes()), long(nq), rc.iterations, rg.iterations, rg.pcg_iterations, difference,
            residual, q_gpu[map.macro_dof(1, 1)] / L);
    }
}

TEST(DevicePeriodicNewton, MisuseIsRefused)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    const test::ElasticBox box = test::make_elastic_box(2, { 3, 2 }, -1, 0, 0, 5);
    test::BoxCell cell(box.mesh);
    gpu::DeviceElasticMesh mesh;
    mesh.upload(2, box.rest_flat(), box.elements_flat(), box.models, box.mu_vector(), box.lambda_vector());
    gpu::DevicePeriodicMap& device_map = cell.device(box.rest_flat());
    gpu::DeviceNewton solver(mesh, {});
    std::vector<double> q(size_t(device_map.num_reduced()), 0.0), x = box.rest_flat();
    const std::vector<double> zero(x.size(), 0.0);
    EXPECT_THROW(solver.solve_periodic(q, q, {}, 1.0, zero, 1.0, 1.0, {}), std::logic_error);
    EXPECT_THROW(solver.set_periodic(&device_map, std::vector<char>(3, 0)), std::invalid_argument);
    solver.set_periodic(&device_map, std::vector<char>(q.size(), 0));
    EXPECT_THROW(solver.solve(x, {}, 1.0, zero, x, 1.0, 1.0, {}), std::logic_error);
    EXPECT_THROW(
        solver.solve_periodic(q, std::vector<double>(2, 0.0), {}, 1.0, zero, 1.0, 1.0, {}), std::invalid_argument);
}
