// DeviceNewton (cuda/solver/device_newton.hpp) on the GPU against the CPU NewtonSolver on the same
// problems, built with the forward library: a 3D cantilever's implicit-Euler step under gravity,
// a static 2D strip whose end is prescribed (lifting), every material model; determinism, a failed
// solve leaving x untouched, inverted starts. The inversion bound's host code (forward/kernels/inversion_bound.hpp)
// is checked against the CPU's inversion_free_step without a GPU; everything else skips without
// one. DISABLED_TimingsOfA200kTetBeam prints per-phase times (--gtest_also_run_disabled_tests).
//
// Tolerance of the converged positions: both solvers stop at max |g_free| <= tol force_scale
// (tol = 1e-10), so each converged x lies within its Newton correction |H^-1 g| of the exact
// minimizer (to first order); the tests print that correction for both (computed on the CPU with
// the true Hessian at each x) and require max |x_gpu - x_cpu| <= 1e-6 max |x_cpu - x_start|, and
// that the corrections themselves stay below that bound (which is what makes it a valid one).

#include "cuda/elastic/device_elastic_mesh.hpp"
#include "cuda/solver/device_newton.hpp"
#include "forward/fem/fe_space.hpp"
#include "forward/kernels/inversion_bound.hpp"
#include "forward/materials/material.hpp"
#include "forward/mesh/mesh.hpp"
#include "forward/potentials/elastic_potential.hpp"
#include "forward/potentials/inertia_potential.hpp"
#include "forward/scene/scene.hpp"
#include "forward/solver/linear_solver.hpp"
#include "forward/solver/newton.hpp"
#include "forward/solver/problem.hpp"
#include "forward/solver/sparse_assembler.hpp"
#include "tests/cuda/elastic_test_utils.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

using namespace diffipc;

namespace {

constexpr double TOLERANCE = 1e-10; ///< residual tolerance of both solvers
constexpr double X_TOLERANCE = 1e-6; ///< of the displacement scale

StepStatus cpu_status(gpu::DeviceStepStatus s) { return StepStatus(int(s)); }

std::vector<double> to_std(const VectorXd& v) { return std::vector<double>(v.data(), v.data() + v.size()); }
VectorXd to_eigen(const std::vector<double>& v) { return Eigen::Map<const VectorXd>(v.data(), Index(v.size())); }

/// One Newton problem of the forward library: E = [inertia] + w (Psi - f^T (x - X)), with its
/// Dirichlet data, start, scales. Held by pointer (the Problem points into it).
struct Case {
    std::string name;
    Mesh mesh;
    std::unique_ptr<FESpace> space;
    std::vector<MaterialModel> models;
    VectorXd mu, lambda, density;
    std::unique_ptr<ElasticPotential> elastic;
    std::unique_ptr<InertiaPotential> inertia; // null: static
    std::unique_ptr<ExternalForcePotential> external;
    Problem problem;
    double w = 1;
    VectorXd start, inertial_target, force, target;
    std::vector<char> constrained;
    double force_scale = 1, step_scale = 1;

    bool dynamic() const { return inertia != nullptr; }
    VectorXd rest() const { return flatten(mesh.rest_positions); }
    /// #dofs lumped masses (empty when static).
    std::vector<double> dof_masses() const
    {
        if (!inertia)
            return {};
        std::vector<double> m(size_t(mesh.num_dofs()));
        for (size_t k = 0; k < m.size(); ++k)
            m[k] = inertia->lumped_masses()[Index(k) / mesh.dim];
        return m;
    }
    /// Sets up the potentials and the problem (after mesh, models, mu, lambda, density are set).
    void build(bool with_inertia, double weight, const VectorXd& gravity)
    {
        space = std::make_unique<FESpace>(mesh);
        elastic = std::make_unique<ElasticPotential>(*space, models, mu, lambda);
        external = std::make_unique<ExternalForcePotential>(rest());
        const VectorXd lumped = space->lumped_masses(density);
        force.resize(mesh.num_dofs());
        for (Index v = 0; v < mesh.num_vertices(); ++v)
            force.segment(v * mesh.dim, mesh.dim) = lumped[v] * gravity;
        external->set_force(force);
        w = weight;
        if (with_inertia) {
            inertia = std::make_unique<InertiaPotential>(*space, density, false);
            problem.add(inertia.get(), 1.0);
        }
        problem.add(elastic.get(), w);
        problem.add(external.get(), w);
        // The simulator's force scale: w * mean E * mean volume^((d-1)/d), E from the Lame parameters.
        double mean_E = 0, mean_volume = 0;
        for (Index e = 0; e < mesh.num_elements(); ++e) {
            mean_E += mu[e] * (3 * lambda[e] + 2 * mu[e]) / (lambda[e] + mu[e]);
            mean_volume += space->rest_volume(e);
        }
        mean_E /= double(mesh.num_elements());
        mean_volume /= double(mesh.num_elements());
        force_scale = w * mean_E * std::pow(mean_volume, double(mesh.dim - 1) / mesh.dim);
    }
};

void set_material(Case& c, MaterialModel model, double E, double nu, double rho)
{
    const Index ne = c.mesh.num_elements();
    c.models.assign(size_t(ne), model);
    c.mu = VectorXd::Constant(ne, lame_mu(E, nu));
    c.lambda = VectorXd::Constant(ne, lame_lambda(E, nu));
    c.density = VectorXd::Constant(ne, rho);
}

/// A 1 x 0.2 x 0.2 m beam clamped at x = 0, one implicit-Euler step of dt from rest positions with a
/// downward velocity growing along the beam (v_y = -X / 1 m per s) under gravity.
std::unique_ptr<Case> cantilever(MaterialModel model, const std::vector<int>& cells, double dt = 0.1, double E = 1e5)
{
    auto c = std::make_unique<Case>();
    c->name = "3D cantilever (" + to_string(model) + ")";
    VectorXi n(3);
    n << cells[0], cells[1], cells[2];
    c->mesh = box_mesh(3, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1.0, 0.2, 0.2), n);
    set_material(*c, model, E, 0.3, 1000);
    c->build(true, dt * dt, Eigen::Vector3d(0, -9.81, 0));
    c->start = c->rest();
    c->inertial_target = c->start;
    c->target = c->start;
    c->constrained.assign(size_t(c->mesh.num_dofs()), 0);
    for (Index v = 0; v < c->mesh.num_vertices(); ++v) {
        const double X = c->mesh.rest_positions(v, 0);
        c->inertial_target[v * 3 + 1] -= dt * X;
        if (X == 0)
            for (int i = 0; i < 3; ++i)
                c->constrained[size_t(v * 3 + i)] = 1;
    }
    c->step_scale = dt;
    return c;
}

/// A static 1 x 0.2 m strip (plane strain) under gravity, clamped at x = 0, its end x = 1 prescribed to
/// move by (stretch, 0.02) m: the solve lifts it there first.
std::unique_ptr<Case> stretched_strip(MaterialModel model, const std::vector<int>& cells, double stretch)
{
    auto c = std::make_unique<Case>();
    c->name = "2D stretched strip (" + to_string(model) + ")";
    VectorXi n(2);
    n << cells[0], cells[1];
    c->mesh = box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(1.0, 0.2), n);
    set_material(*c, model, 1e5, 0.3, 1000);
    c->build(false, 1.0, Eigen::Vector2d(0, -9.81));
    c->start = c->rest();
    c->target = c->start;
    c->constrained.assign(size_t(c->mesh.num_dofs()), 0);
    for (Index v = 0; v < c->mesh.num_vertices(); ++v) {
        const double X = c->mesh.rest_positions(v, 0);
        if (X == 0 || X == 1.0)
            c->constrained[size_t(v * 2)] = c->constrained[size_t(v * 2 + 1)] = 1;
        if (X == 1.0) {
            c->target[v * 2] += stretch;
            c->target[v * 2 + 1] += 0.02;
        }
    }
    c->step_scale = std::sqrt(1.0 + 0.04); // the bounding box's diagonal
    return c;
}

NewtonSettings cpu_settings(int max_iterations = 100)
{
    NewtonSettings s;
    s.residual_tolerance = TOLERANCE;
    s.max_iterations = max_iterations;
    // Both solvers always project and never extend a step here.
    s.adaptive_projection = false;
    s.step_extension = false;
    return s;
}

gpu::DeviceNewtonSettings gpu_settings(int max_iterations = 100)
{
    gpu::DeviceNewtonSettings s;
    s.residual_tolerance = TOLERANCE;
    s.max_iterations = max_iterations;
    s.step_extension = false;
    return s;
}

struct CpuRun {
    NewtonResult result;
    VectorXd x;
    double seconds = 0;
};

CpuRun cpu_solve(const Case& c, const VectorXd& start, const NewtonSettings& settings, LoadControl* control = nullptr)
{
    if (c.inertia)
        c.inertia->set_target(c.inertial_target);
    SparseAssembler assembler;
    assembler.build(c.mesh.dim, c.mesh.num_vertices(), c.mesh.elements);
    LinearSolver linear(LinearSolverType::CHOLMOD);
    const NewtonSolver newton(c.problem, assembler, linear, settings);
    CpuRun run;
    run.x = start;
    const auto t0 = std::chrono::steady_clock::now();
    run.result = newton.solve(run.x, c.target, c.constrained, c.force_scale, c.step_scale, control);
    run.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return run;
}

/// The mesh on the GPU and a DeviceNewton on it (held together: the solver refers to the mesh).
struct GpuSolver {
    gpu::DeviceElasticMesh mesh;
    std::unique_ptr<gpu::DeviceNewton> newton;
};

std::unique_ptr<GpuSolver> make_gpu(const Case& c)
{
    auto s = std::make_unique<GpuSolver>();
    const Mesh& m = c.mesh;
    s->mesh.upload(m.dim,
        std::vector<double>(m.rest_positions.data(), m.rest_positions.data() + m.rest_positions.size()),
        std::vector<int>(m.elements.data(), m.elements.data() + m.elements.size()), c.models, to_std(c.mu),
        to_std(c.lambda));
    s->newton = std::make_unique<gpu::DeviceNewton>(s->mesh, c.dof_masses());
    s->newton->set_constrained(c.constrained);
    s->newton->set_force_reference(to_std(c.rest()));
    s->newton->set_material_scale(c.models, to_std(c.mu));
    return s;
}

gpu::DeviceNewtonResult gpu_solve(const Case& c, GpuSolver& s, std::vector<double>& x,
    const gpu::DeviceNewtonSettings& settings, gpu::DeviceLoadControl* control = nullptr)
{
    return s.newton->solve(x, c.dynamic() ? to_std(c.inertial_target) : std::vector<double>(), c.w, to_std(c.force),
        to_std(c.target), c.force_scale, c.step_scale, settings, control);
}

/// The CPU's gradient at x, zero on the constrained dofs.
VectorXd free_gradient(const Case& c, const VectorXd& x)
{
    if (c.inertia)
        c.inertia->set_target(c.inertial_target);
    VectorXd g;
    c.problem.gradient(x, g);
    for (Index i = 0; i < g.size(); ++i)
        if (c.constrained[size_t(i)])
            g[i] = 0;
    return g;
}

/// max |g_free(x)| / force_scale with the CPU's gradient.
double cpu_residual(const Case& c, const VectorXd& x)
{
    return free_gradient(c, x).lpNorm<Eigen::Infinity>() / c.force_scale;
}

/// max |H^-1 g_free| at x with the CPU's true Hessian (projected if that is not positive definite):
/// the first-order distance from x to the exact minimizer.
double newton_correction(const Case& c, const VectorXd& x)
{
    const VectorXd g = free_gradient(c, x);
    SparseAssembler H;
    H.build(c.mesh.dim, c.mesh.num_vertices(), c.mesh.elements);
    LinearSolver linear(LinearSolverType::CHOLMOD);
    for (bool project : { false, true }) {
        c.problem.hessian(x, project, H);
        H.apply_constraints(c.constrained);
        if (linear.factorize(H.matrix(), /*allow_fallback=*/false))
            return linear.solve(g).lpNorm<Eigen::Infinity>();
    }
    return std::numeric_limits<double>::quiet_NaN();
}

void print(const char* who, const gpu::DeviceNewtonResult& r)
{
    std::printf("  %s: %s, %d Newton iterations, %d PCG iterations (%d capped), %d line-search cuts, residual %.2e%s; "
                "assembly %.2f ms, solve %.2f ms, line search %.2f ms\n",
        who, to_string(cpu_status(r.status)).c_str(), r.iterations, r.pcg_iterations, r.pcg_capped, r.line_search_cuts,
        r.residual, r.roundoff_limited ? " (round-off limited)" : "", 1e3 * r.assembly_time, 1e3 * r.solve_time,
        1e3 * r.line_search_time);
}

void print(const char* who, const NewtonResult& r, double seconds)
{
    std::printf("  %s: %s, %d Newton iterations, %d line-search cuts, residual %.2e%s; %.2f ms (assembly %.2f, "
                "factorization %.2f, solve %.2f, line search %.2f)\n",
        who, to_string(r.status).c_str(), r.iterations, r.line_search_cuts, r.residual,
        r.roundoff_limited ? " (round-off limited)" : "", 1e3 * seconds, 1e3 * r.times.assembly,
        1e3 * r.times.factorization, 1e3 * r.times.solve, 1e3 * r.times.line_search);
}

/// Solves the case on both sides from its start and compares (see the file comment for the tolerance).
void compare_with_cpu(const Case& c)
{
    SCOPED_TRACE(c.name);
    const CpuRun cpu = cpu_solve(c, c.start, cpu_settings());
    auto gpu = make_gpu(c);
    std::vector<double> x = to_std(c.start);
    const gpu::DeviceNewtonResult r = gpu_solve(c, *gpu, x, gpu_settings());
    std::printf("%s: %d elements, %d dofs\n", c.name.c_str(), int(c.mesh.num_elements()), int(c.mesh.num_dofs()));
    print("CPU", cpu.result, cpu.seconds);
    print("GPU", r);
    ASSERT_EQ(to_string(cpu_status(r.status)), to_string(cpu.result.status));
    ASSERT_EQ(cpu.result.status, StepStatus::CONVERGED);
    const VectorXd x_gpu = to_eigen(x);
    const double scale = (cpu.x - c.start).lpNorm<Eigen::Infinity>();
    const double difference = (x_gpu - cpu.x).lpNorm<Eigen::Infinity>();
    const double correction_cpu = newton_correction(c, cpu.x), correction_gpu = newton_correction(c, x_gpu);
    const double residual_at_gpu_x = cpu_residual(c, x_gpu);
    std::printf("  displacement scale %.4e m; max |x_gpu - x_cpu| = %.3e m (%.2e of the scale; bound %.0e); Newton "
                "corrections: CPU %.2e m, GPU %.2e m; CPU residual at the GPU's x %.2e\n",
        scale, difference, difference / scale, X_TOLERANCE, correction_cpu, correction_gpu, residual_at_gpu_x);
    EXPECT_GT(scale, 0);
    EXPECT_LE(r.residual, TOLERANCE);
    // The CPU's gradient at the GPU's x: the same test, up to the two gradients' rounding.
    EXPECT_LE(residual_at_gpu_x, 2 * TOLERANCE);
    EXPECT_LE(difference, X_TOLERANCE * scale);
    EXPECT_LE(correction_cpu + correction_gpu, X_TOLERANCE * scale);
    // The prescribed dofs are exactly at their targets (lifting's snap).
    for (Index i = 0; i < x_gpu.size(); ++i)
        if (c.constrained[size_t(i)])
            ASSERT_EQ(x_gpu[i], c.target[i]) << "dof " << i;
}

} // namespace

// ---- Host code of the kernels (no GPU needed) ----

TEST(DeviceNewtonHost, InversionBoundEqualsTheCpuBound)
{
    for (int dim : { 2, 3 }) {
        Mesh mesh = dim == 2
            ? box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1), Eigen::Vector2i(6, 6))
            : box_mesh(3, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 1), Eigen::Vector3i(3, 3, 3));
        std::mt19937 rng(7 + unsigned(dim));
        std::uniform_real_distribution<double> u(-1, 1);
        const VectorXd rest = flatten(mesh.rest_positions);
        int cut = 0, zero = 0;
        for (int trial = 0; trial < 20; ++trial) {
            VectorXd x = rest, p(rest.size());
            for (Index i = 0; i < x.size(); ++i) {
                x[i] += 0.02 * u(rng);
                p[i] = (0.05 + 0.1 * trial) * u(rng);
            }
            if (trial == 19) // an inverted element at x: no step is admissible
                std::swap(x[mesh.elements(0, 0) * dim], x[mesh.elements(0, 1) * dim]);
            double bound = 1.0;
            for (Index e = 0; e < mesh.num_elements(); ++e) {
                double xe[12], pe[12], c[4];
                for (int a = 0; a <= dim; ++a)
                    for (int i = 0; i < dim; ++i) {
                        xe[a * dim + i] = x[mesh.elements(e, a) * dim + i];
                        pe[a * dim + i] = p[mesh.elements(e, a) * dim + i];
                    }
                const Eigen::Vector4d cpu = volume_polynomial(mesh, e, x, p);
                if (dim == 2) {
                    gpu::volume_polynomial<2>(xe, pe, c);
                    bound = std::min(bound, gpu::element_step_bound<2>(xe, pe, 0.1));
                } else {
                    gpu::volume_polynomial<3>(xe, pe, c);
                    bound = std::min(bound, gpu::element_step_bound<3>(xe, pe, 0.1));
                }
                for (int k = 0; k < 4; ++k)
                    EXPECT_EQ(c[k], cpu[k]) << "dim " << dim << " element " << e << " coefficient " << k;
            }
            const double cpu_bound = inversion_free_step(mesh, x, p, 0.1);
            EXPECT_EQ(bound, cpu_bound) << "dim " << dim << " trial " << trial;
            cut += cpu_bound > 0 && cpu_bound < 1;
            zero += cpu_bound == 0;
        }
        EXPECT_GE(cut, 10) << "the random steps should mostly be cut by the bound";
        EXPECT_EQ(zero, 1);
    }
}

// ---- GPU against CPU ----

TEST(DeviceNewton, CantileverStepUnderGravityEqualsCpu)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    compare_with_cpu(*cantilever(MaterialModel::NEO_HOOKEAN, { 16, 4, 4 })); // 1536 tetrahedra
}

TEST(DeviceNewton, StaticStripWithLiftingEqualsCpu)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    compare_with_cpu(*stretched_strip(MaterialModel::NEO_HOOKEAN, { 20, 4 }, 0.2)); // 160 triangles
}

TEST(DeviceNewton, EveryMaterialModelEqualsCpu)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    for (MaterialModel model :
        { MaterialModel::LINEAR, MaterialModel::STVK, MaterialModel::NEO_HOOKEAN, MaterialModel::STABLE_NEO_HOOKEAN }) {
        compare_with_cpu(*cantilever(model, { 8, 2, 2 }));
        compare_with_cpu(*stretched_strip(model, { 12, 3 }, 0.1));
    }
}

/// Load control (DeviceLoadControl, the CPU's LoadControl) against NewtonSolver::solve with one: the
/// direction a is the unconstrained solution's displacement on the free dofs, and the level puts
/// a^T x half of |a|^2 beyond that solution's, so the constraint carries load (a nonzero multiplier).
void compare_control_with_cpu(const Case& c)
{
    SCOPED_TRACE(c.name);
    const CpuRun free_run = cpu_solve(c, c.start, cpu_settings());
    ASSERT_EQ(free_run.result.status, StepStatus::CONVERGED);
    VectorXd a = free_run.x - c.start;
    for (Index i = 0; i < a.size(); ++i)
        if (c.constrained[size_t(i)])
            a[i] = 0;
    ASSERT_GT(a.squaredNorm(), 0);
    LoadControl cpu_control;
    cpu_control.direction = a;
    cpu_control.level = a.dot(free_run.x) + 0.5 * a.squaredNorm();
    cpu_control.tolerance = 1e-9 * a.squaredNorm();
    // The CPU as it runs load control in a simulation: the true Hessian after full steps, by LDL^T where
    // it is indefinite (with the projected one only, this solve converges linearly and ends at 100
    // iterations with a residual of 1e-9).
    NewtonSettings settings = cpu_settings();
    settings.adaptive_projection = true;
    const CpuRun cpu = cpu_solve(c, c.start, settings, &cpu_control);

    gpu::DeviceLoadControl gpu_control;
    gpu_control.direction = to_std(a);
    gpu_control.level = cpu_control.level;
    gpu_control.tolerance = cpu_control.tolerance;
    auto gpu = make_gpu(c);
    std::vector<double> x = to_std(c.start);
    const gpu::DeviceNewtonResult r = gpu_solve(c, *gpu, x, gpu_settings(), &gpu_control);
    print("CPU, load control", cpu.result, cpu.seconds);
    print("GPU, load control", r);
    const VectorXd x_gpu = to_eigen(x);
    const double scale = (cpu.x - c.start).lpNorm<Eigen::Infinity>();
    const double difference = (x_gpu - cpu.x).lpNorm<Eigen::Infinity>();
    // The CPU's residual at the GPU's x: max |g - lambda a| on the free dofs, lambda by least squares.
    VectorXd g = free_gradient(c, x_gpu);
    g -= (a.dot(g) / a.squaredNorm()) * a;
    const double residual_at_gpu_x = g.lpNorm<Eigen::Infinity>() / c.force_scale;
    std::printf("  load control: max |x_gpu - x_cpu| = %.2e of the displacement scale %.3e m; multipliers CPU "
                "%.6e, GPU %.6e; |a.x - level| / |a|^2 GPU %.1e; CPU residual at the GPU's x %.2e\n",
        difference / scale, scale, cpu_control.multiplier, gpu_control.multiplier,
        std::abs(a.dot(x_gpu) - cpu_control.level) / a.squaredNorm(), residual_at_gpu_x);
    ASSERT_EQ(cpu.result.status, StepStatus::CONVERGED);
    ASSERT_EQ(to_string(cpu_status(r.status)), to_string(cpu.result.status));
    EXPECT_GT(std::abs(cpu_control.multiplier), 0) << "the constraint carries no load: a weak test";
    EXPECT_LE(std::abs(a.dot(x_gpu) - cpu_control.level), cpu_control.tolerance);
    EXPECT_LE(r.residual, TOLERANCE);
    EXPECT_LE(residual_at_gpu_x, 2 * TOLERANCE);
    EXPECT_LE(difference, X_TOLERANCE * scale);
    EXPECT_NEAR(gpu_control.multiplier, cpu_control.multiplier, 1e-6 * std::abs(cpu_control.multiplier));
    for (Index i = 0; i < x_gpu.size(); ++i)
        if (c.constrained[size_t(i)])
            ASSERT_EQ(x_gpu[i], c.target[i]) << "dof " << i;
}

TEST(DeviceNewton, LoadControlEqualsCpu)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    compare_control_with_cpu(*cantilever(MaterialModel::NEO_HOOKEAN, { 8, 2, 2 })); // dynamic, 3D
    compare_control_with_cpu(*stretched_strip(MaterialModel::NEO_HOOKEAN, { 12, 3 }, 0.1)); // static, lifting, 2D
}

// ---- Determinism, failures ----

TEST(DeviceNewton, RepeatedSolvesGiveTheSameBits)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    for (auto& c : { cantilever(MaterialModel::NEO_HOOKEAN, { 8, 2, 2 }),
             stretched_strip(MaterialModel::STABLE_NEO_HOOKEAN, { 12, 3 }, 0.2) }) {
        SCOPED_TRACE(c->name);
        auto a = make_gpu(*c), b = make_gpu(*c);
        std::vector<double> x1 = to_std(c->start), x2 = x1, x3 = x1;
        const gpu::DeviceNewtonResult r1 = gpu_solve(*c, *a, x1, gpu_settings());
        const gpu::DeviceNewtonResult r2 = gpu_solve(*c, *a, x2, gpu_settings()); // the same solver again
        const gpu::DeviceNewtonResult r3 = gpu_solve(*c, *b, x3, gpu_settings()); // another one
        ASSERT_EQ(r1.status, gpu::DeviceStepStatus::CONVERGED);
        for (const auto* r : { &r2, &r3 }) {
            EXPECT_EQ(r->status, r1.status);
            EXPECT_EQ(r->iterations, r1.iterations);
            EXPECT_EQ(r->pcg_iterations, r1.pcg_iterations);
            EXPECT_EQ(std::memcmp(&r->residual, &r1.residual, sizeof(double)), 0);
        }
        EXPECT_EQ(std::memcmp(x1.data(), x2.data(), x1.size() * sizeof(double)), 0);
        EXPECT_EQ(std::memcmp(x1.data(), x3.data(), x1.size() * sizeof(double)), 0);
    }
}

TEST(DeviceNewton, AFailedSolveLeavesXUnchanged)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    for (auto& c : { cantilever(MaterialModel::NEO_HOOKEAN, { 8, 2, 2 }),
             stretched_strip(MaterialModel::NEO_HOOKEAN, { 12, 3 }, 0.2) }) {
        SCOPED_TRACE(c->name);
        auto s = make_gpu(*c);
        std::vector<double> x = to_std(c->start);
        const std::vector<double> before = x;
        const gpu::DeviceNewtonResult r = gpu_solve(*c, *s, x, gpu_settings(1));
        const CpuRun cpu = cpu_solve(*c, c->start, cpu_settings(1));
        EXPECT_EQ(r.status, gpu::DeviceStepStatus::NEWTON_EXHAUSTED);
        EXPECT_EQ(cpu.result.status, StepStatus::NEWTON_EXHAUSTED);
        EXPECT_EQ(r.iterations, 1);
        EXPECT_EQ(std::memcmp(x.data(), before.data(), x.size() * sizeof(double)), 0);
    }
}

TEST(DeviceNewton, AnInvertedStartFailsAsOnTheCpu)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    for (MaterialModel model :
        { MaterialModel::LINEAR, MaterialModel::STVK, MaterialModel::NEO_HOOKEAN, MaterialModel::STABLE_NEO_HOOKEAN }) {
        auto c = stretched_strip(model, { 10, 2 }, 0.1);
        SCOPED_TRACE(c->name);
        // The interior vertex at (0.5, 0.1) pushed above the top edge: the triangles above it invert.
        for (Index v = 0; v < c->mesh.num_vertices(); ++v)
            if ((c->mesh.rest_positions.row(v) - Eigen::RowVector2d(0.5, 0.1)).norm() < 1e-9)
                c->start[v * 2 + 1] += 0.15;
        ASSERT_LT(c->space->min_volume_ratio(c->start), 0);
        const CpuRun cpu = cpu_solve(*c, c->start, cpu_settings());
        auto s = make_gpu(*c);
        std::vector<double> x = to_std(c->start);
        const gpu::DeviceNewtonResult r = gpu_solve(*c, *s, x, gpu_settings());
        std::printf("%s from an inverted start: CPU %s, GPU %s\n", c->name.c_str(),
            to_string(cpu.result.status).c_str(), to_string(cpu_status(r.status)).c_str());
        EXPECT_NE(cpu.result.status, StepStatus::CONVERGED);
        EXPECT_EQ(to_string(cpu_status(r.status)), to_string(cpu.result.status));
        if (model == MaterialModel::NEO_HOOKEAN)
            EXPECT_EQ(r.status, gpu::DeviceStepStatus::INVALID_INITIAL_STATE); // log J of a negative J: +inf
        EXPECT_EQ(x, to_std(c->start));
    }
}

TEST(DeviceNewton, RejectsBadInput)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    auto c = stretched_strip(MaterialModel::NEO_HOOKEAN, { 4, 2 }, 0.1);
    auto s = make_gpu(*c);
    std::vector<double> x = to_std(c->start);
    const std::vector<double> short_vector(3, 0.0);
    EXPECT_THROW(s->newton->set_constrained(std::vector<char>(3, 0)), std::invalid_argument);
    EXPECT_THROW(gpu::DeviceNewton(s->mesh, short_vector), std::invalid_argument);
    EXPECT_THROW(gpu::DeviceNewton(s->mesh, std::vector<double>(x.size(), -1.0)), std::invalid_argument);
    EXPECT_THROW(
        s->newton->solve(x, {}, 1.0, short_vector, to_std(c->target), 1, 1, gpu_settings()), std::invalid_argument);
    EXPECT_THROW(
        s->newton->solve(x, {}, 0.0, to_std(c->force), to_std(c->target), 1, 1, gpu_settings()), std::invalid_argument);
    gpu::DeviceNewtonSettings bad = gpu_settings();
    bad.terminal_window = 0.5;
    EXPECT_THROW(s->newton->solve(x, {}, 1.0, to_std(c->force), to_std(c->target), 1, 1, bad), std::invalid_argument);
    bad = gpu_settings();
    bad.terminal_factor = -1;
    EXPECT_THROW(s->newton->solve(x, {}, 1.0, to_std(c->force), to_std(c->target), 1, 1, bad), std::invalid_argument);
    bad = gpu_settings();
    bad.lifting_forcing_max = 0;
    EXPECT_THROW(s->newton->solve(x, {}, 1.0, to_std(c->force), to_std(c->target), 1, 1, bad), std::invalid_argument);
    // Masses for a proximal solve (set_lumped_mass) of the wrong count or negative are refused and leave the
    // static solver static: a solve without an inertial target runs. With masses it is dynamic and needs one;
    // empty masses make it static again.
    EXPECT_THROW(s->newton->set_lumped_mass(short_vector), std::invalid_argument);
    EXPECT_THROW(s->newton->set_lumped_mass(std::vector<double>(x.size(), -1.0)), std::invalid_argument);
    std::vector<double> y = x;
    EXPECT_NO_THROW(s->newton->solve(y, {}, 1.0, to_std(c->force), to_std(c->target), 1, 1, gpu_settings()));
    s->newton->set_lumped_mass(std::vector<double>(x.size(), 1.0));
    y = x;
    EXPECT_THROW(
        s->newton->solve(y, {}, 1.0, to_std(c->force), to_std(c->target), 1, 1, gpu_settings()), std::invalid_argument);
    s->newton->set_lumped_mass({});
    y = x;
    EXPECT_NO_THROW(s->newton->solve(y, {}, 1.0, to_std(c->force), to_std(c->target), 1, 1, gpu_settings()));
    // A load control of the wrong size, zero, not finite, or nonzero on a constrained dof is refused;
    // the next solve without one runs unconstrained (the control is cleared however a solve ends).
    auto control_with = [&](std::vector<double> direction) {
        gpu::DeviceLoadControl control;
        control.direction = std::move(direction);
        control.level = 0;
        return control;
    };
    size_t free_dof = 0, fixed_dof = 0;
    while (c->constrained[free_dof])
        ++free_dof;
    while (!c->constrained[fixed_dof])
        ++fixed_dof;
    std::vector<double> on_fixed(x.size(), 0.0), not_finite(x.size(), 0.0);
    on_fixed[free_dof] = on_fixed[fixed_dof] = 1;
    not_finite[free_dof] = std::numeric_limits<double>::quiet_NaN();
    for (std::vector<double> direction : { short_vector, std::vector<double>(x.size(), 0.0), on_fixed, not_finite }) {
        gpu::DeviceLoadControl control = control_with(direction);
        y = x;
        EXPECT_THROW(s->newton->solve(y, {}, 1.0, to_std(c->force), to_std(c->target), 1, 1, gpu_settings(), &control),
            std::invalid_argument);
        EXPECT_EQ(y, x);
    }
    y = x;
    const gpu::DeviceNewtonResult unconstrained
        = s->newton->solve(y, {}, 1.0, to_std(c->force), to_std(c->target), 1, 1, gpu_settings());
    std::vector<double> z = x;
    auto fresh = make_gpu(*c);
    const gpu::DeviceNewtonResult reference
        = fresh->newton->solve(z, {}, 1.0, to_std(c->force), to_std(c->target), 1, 1, gpu_settings());
    EXPECT_EQ(unconstrained.iterations, reference.iterations);
    EXPECT_EQ(y, z);
}

TEST(DeviceNewton, TheLastStepLandsWellBelowTheTolerance)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    // With the terminal forcing (DeviceNewtonSettings::terminal_factor) the last linear solve is tight, so
    // that the converged state sits well below the tolerance, as after the CPU's exact last step; without
    // it the inexact solves may stop just under the tolerance. The residual is the CPU's own, at the GPU's
    // state. At least one of the cases must end above a tenth of the tolerance without it (else this test
    // could not tell the difference).
    int distinguishing = 0;
    for (const double tolerance : { 1e-6, 1e-8 })
        for (const bool dynamic : { true, false }) {
            auto c = dynamic ? cantilever(MaterialModel::NEO_HOOKEAN, { 16, 4, 4 })
                             : stretched_strip(MaterialModel::NEO_HOOKEAN, { 20, 4 }, 0.2);
            double residual[2];
            int iterations[2];
            for (const int k : { 0, 1 }) {
                auto s = make_gpu(*c);
                std::vector<double> x = to_std(c->start);
                gpu::DeviceNewtonSettings settings = gpu_settings();
                settings.residual_tolerance = tolerance;
                settings.terminal_factor = k == 0 ? 0.0 : 1e-2;
                const gpu::DeviceNewtonResult r = gpu_solve(*c, *s, x, settings);
                ASSERT_EQ(r.status, gpu::DeviceStepStatus::CONVERGED);
                residual[k] = cpu_residual(*c, Eigen::Map<const VectorXd>(x.data(), Index(x.size())));
                iterations[k] = r.pcg_iterations;
            }
            std::printf("  %s, tolerance %.0e: the CPU's residual at the GPU's state %.2e without the terminal "
                        "forcing (%d PCG iterations), %.2e with it (%d)\n",
                dynamic ? "cantilever, implicit Euler" : "static strip", tolerance, residual[0], iterations[0],
                residual[1], iterations[1]);
            EXPECT_LE(residual[1], 0.1 * tolerance);
            distinguishing += residual[0] > 0.1 * tolerance;
        }
    EXPECT_GT(distinguishing, 0);
}

// The adjoint's solve with the multigrid (set_adjoint_multigrid) on a hierarchy of several levels,
// reached through DeviceNewton's plan (its coarsest level capped at 60 dofs), with vertices fixed in
// one component only: the same solution as block-Jacobi, in fewer iterations.
TEST(DeviceNewton, AdjointMultigridOnSeveralLevelsEqualsBlockJacobi)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    const int dim = 3;
    const test::ElasticBox box
        = test::make_elastic_box(dim, { 14, 6, 6 }, int(MaterialModel::NEO_HOOKEAN), 0.05, 0.05, 19);
    gpu::DeviceElasticMesh mesh;
    mesh.upload(dim, box.rest_flat(), box.elements_flat(), box.models, box.mu_vector(), box.lambda_vector());
    const Index nv = box.mesh.num_vertices();
    const double x_max = box.mesh.rest_positions.col(0).maxCoeff();
    std::vector<char> fixed(size_t(nv * dim), 0);
    for (Index v = 0; v < nv; ++v) {
        if (box.mesh.rest_positions(v, 0) == 0)
            for (int i = 0; i < dim; ++i)
                fixed[size_t(v * dim + i)] = 1;
        else if (box.mesh.rest_positions(v, 0) == x_max)
            fixed[size_t(v * dim + 1)] = 1; // rollers
    }
    gpu::DeviceNewton newton(mesh, {});
    newton.set_constrained(fixed);
    std::mt19937 random(3);
    std::uniform_real_distribution<double> uniform(-1, 1);
    std::vector<double> b(fixed.size());
    for (double& v : b)
        v = uniform(random);
    const std::vector<double> x = box.x_vector();
    std::vector<double> y_bj, y_mg;
    const gpu::PcgResult bj = newton.solve_true_hessian(x, 1.0, b, y_bj, 1e-11, 20000);
    EXPECT_EQ(newton.adjoint_multigrid_levels(), -1) << "planned without the multigrid";
    newton.set_adjoint_multigrid(true, 2, 60);
    const gpu::PcgResult mg = newton.solve_true_hessian(x, 1.0, b, y_mg, 1e-11, 20000);
    ASSERT_TRUE(bj.converged);
    ASSERT_TRUE(mg.converged);
    EXPECT_GE(newton.adjoint_multigrid_levels(), 2) << "a hierarchy of several levels";
    EXPECT_LE(mg.relative_residual, 1e-10);
    const double difference = (to_eigen(y_mg) - to_eigen(y_bj)).norm() / to_eigen(y_bj).norm();
    EXPECT_LE(difference, 1e-8);
    EXPECT_LT(2 * mg.iterations, bj.iterations) << "the multigrid fell back to block-Jacobi, or did not help";
    for (size_t k = 0; k < fixed.size(); ++k)
        if (fixed[k])
            ASSERT_EQ(y_mg[k], 0.0);
    std::printf("  %zu dofs, %d multigrid levels: block-Jacobi %d PCG iterations, multigrid %d; solutions within "
                "%.1e\n",
        fixed.size(), newton.adjoint_multigrid_levels(), bj.iterations, mg.iterations, difference);
    EXPECT_THROW(newton.set_adjoint_multigrid(true, 0, -1), std::invalid_argument);
}

// ---- Timing (prints; asserts only that both converge) ----

// A 2 x 0.5 x 0.5 m neo-Hookean beam (E = 1e5 Pa, nu = 0.3, 1000 kg/m^3) of 80 x 20 x 20 cubes
// (192,000 tetrahedra, 107,163 dofs) clamped at x = 0, three implicit-Euler steps of 0.01 s from rest
// under gravity on the GPU; the first step also with the CPU NewtonSolver (its default settings,
// all threads of the machine) for scale.
TEST(DeviceNewton, DISABLED_TimingsOfA200kTetBeam)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    std::printf("device: %s\n", gpu::cuda_device_description().c_str());
    const double dt = 0.01;
    auto c = std::make_unique<Case>();
    c->name = "beam";
    VectorXi n(3);
    n << 80, 20, 20;
    c->mesh = box_mesh(3, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(2.0, 0.5, 0.5), n);
    set_material(*c, MaterialModel::NEO_HOOKEAN, 1e5, 0.3, 1000);
    c->build(true, dt * dt, Eigen::Vector3d(0, -9.81, 0));
    c->start = c->rest();
    c->inertial_target = c->start;
    c->target = c->start;
    c->constrained.assign(size_t(c->mesh.num_dofs()), 0);
    for (Index v = 0; v < c->mesh.num_vertices(); ++v)
        if (c->mesh.rest_positions(v, 0) == 0)
            for (int i = 0; i < 3; ++i)
                c->constrained[size_t(v * 3 + i)] = 1;
    c->step_scale = dt;
    std::printf("mesh: %d tetrahedra, %d dofs\n", int(c->mesh.num_elements()), int(c->mesh.num_dofs()));

    const auto t_setup = std::chrono::steady_clock::now();
    auto s = make_gpu(*c);
    std::printf("GPU setup (upload, pattern, solver): %.1f ms\n",
        1e3 * std::chrono::duration<double>(std::chrono::steady_clock::now() - t_setup).count());

    // Implicit Euler: x~ = x_n + dt v_n; v_{n+1} = (x_{n+1} - x_n) / dt.
    VectorXd x_n = c->start, v_n = VectorXd::Zero(x_n.size()), first_step;
    for (int step = 0; step < 3; ++step) {
        c->inertial_target = x_n + dt * v_n;
        std::vector<double> x = to_std(x_n);
        const auto t0 = std::chrono::steady_clock::now();
        const gpu::DeviceNewtonResult r = gpu_solve(*c, *s, x, gpu_settings());
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        std::printf("GPU step %d: %.1f ms in all (copies included)\n", step, 1e3 * seconds);
        print("GPU", r);
        ASSERT_EQ(r.status, gpu::DeviceStepStatus::CONVERGED);
        const VectorXd x_new = to_eigen(x);
        if (step == 0)
            first_step = x_new;
        v_n = (x_new - x_n) / dt;
        x_n = x_new;
    }

    c->inertial_target = c->start;
    NewtonSettings defaults;
    defaults.residual_tolerance = TOLERANCE;
    const CpuRun cpu = cpu_solve(*c, c->start, defaults);
    print("CPU step 0 (NewtonSolver defaults)", cpu.result, cpu.seconds);
    ASSERT_EQ(cpu.result.status, StepStatus::CONVERGED);
    const double scale = (cpu.x - c->start).lpNorm<Eigen::Infinity>();
    std::printf("step 0: max |x_gpu - x_cpu| = %.3e m of a displacement scale %.3e m\n",
        (first_step - cpu.x).lpNorm<Eigen::Infinity>(), scale);
}

namespace {

TEST(DeviceNewtonHost, StatusesHaveStepStatusNumbers)
{
    // DeviceSolver converts by the number (forward/simulation/device_solver.cpp).
    using D = gpu::DeviceStepStatus;
    EXPECT_EQ(int(D::CONVERGED), int(StepStatus::CONVERGED));
    EXPECT_EQ(int(D::INVALID_INITIAL_STATE), int(StepStatus::INVALID_INITIAL_STATE));
    EXPECT_EQ(int(D::LINEAR_BREAKDOWN), int(StepStatus::LINEAR_BREAKDOWN));
    EXPECT_EQ(int(D::LINE_SEARCH_EXHAUSTED), int(StepStatus::LINE_SEARCH_EXHAUSTED));
    EXPECT_EQ(int(D::NEWTON_EXHAUSTED), int(StepStatus::NEWTON_EXHAUSTED));
    EXPECT_EQ(int(D::NON_FINITE), int(StepStatus::NON_FINITE));
}

} // namespace
