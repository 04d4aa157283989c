// The GPU path of a whole run (scene "device": "gpu", forward/simulation/device_solver.hpp)
// against the CPU path: the same scenes through Simulator, step by step. Skipped without a GPU.

#include "adjoint/adjoint.hpp"
#include "cuda/common/device.hpp"
#include "tests/cuda/elastic_test_utils.hpp"
#include "tests/cuda/simulation/adjoint_test_utils.hpp"
#include "tests/forward/test_utils.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>

using namespace diffipc;
using nlohmann::json;

namespace {

/// Tolerance of the comparison: both solvers stop at residual_tolerance 1e-10 of the force
/// scale; their states then differ by at most about that share of the step's displacement,
/// summed over the steps (the implicit schemes do not amplify it). Asserted: 1e-6 of the
/// largest displacement of the run; the measured differences are printed.
constexpr double RELATIVE_TOLERANCE = 1e-6;

struct Comparison {
    double worst_difference = 0; ///< max over steps and dofs of |x_gpu - x_cpu| (m)
    double largest_displacement = 0; ///< max over steps and dofs of |x_cpu - X| (m)
};

Comparison run_both(json s, const std::string& name)
{
    s["device"] = "cpu";
    Simulator cpu(test::make_scene(s));
    cpu.run();
    s["device"] = "gpu";
    Simulator gpu(test::make_scene(s));
    gpu.run();
    const Trajectory &a = cpu.trajectory(), &b = gpu.trajectory();
    EXPECT_EQ(a.final_status, StepStatus::CONVERGED) << name << ": " << a.failure_message;
    EXPECT_EQ(b.final_status, StepStatus::CONVERGED) << name << ": " << b.failure_message;
    EXPECT_EQ(a.committed(), b.committed()) << name;
    Comparison c;
    const VectorXd& X = a.initial_positions;
    int gpu_iterations = 0, cpu_iterations = 0;
    for (int k = 1; k <= std::min(a.committed(), b.committed()); ++k) {
        const VectorXd& xa = a.step(k).positions;
        const VectorXd& xb = b.step(k).positions;
        c.worst_difference = std::max(c.worst_difference, (xa - xb).lpNorm<Eigen::Infinity>());
        c.largest_displacement = std::max(c.largest_displacement, (xa - X).lpNorm<Eigen::Infinity>());
        EXPECT_LE(b.step(k).residual, s["solver"]["residual_tolerance"].get<double>()) << name << " step " << k;
        gpu_iterations += b.step(k).newton_iterations;
        cpu_iterations += a.step(k).newton_iterations;
    }
    std::printf("  %-44s %2d steps: max |x_gpu - x_cpu| = %.2e m = %.2e of the largest displacement %.3e m; "
                "Newton iterations CPU %d, GPU %d\n",
        name.c_str(), a.committed(), c.worst_difference, c.worst_difference / c.largest_displacement,
        c.largest_displacement, cpu_iterations, gpu_iterations);
    EXPECT_GT(c.largest_displacement, 0) << name;
    EXPECT_LE(c.worst_difference, RELATIVE_TOLERANCE * c.largest_displacement) << name;
    return c;
}

/// A cantilever under gravity, clamped at x = 0 (2D: 1 x 0.2 m, 3D: 1 x 0.2 x 0.2 m).
json cantilever(int dim, const std::string& model, const std::string& integrator, int steps)
{
    json s = dim == 2 ? test::box_scene(2, { 1.0, 0.2 }, { 20, 4 }, model, 1e6, 0.3)
                      : test::box_scene(3, { 1.0, 0.2, 0.2 }, { 10, 2, 2 }, model, 1e6, 0.3);
    std::vector<double> lo(size_t(dim), -1.0), hi(size_t(dim), 1.0), zero(size_t(dim), 0.0);
    hi[0] = 0.0;
    s["dirichlet"] = { { { "body", 0 }, { "region", test::region(lo, hi) }, { "displacement", zero } } };
    s["gravity"] = dim == 2 ? json { 0, -9.81 } : json { 0, -9.81, 0 };
    s["time"] = { { "integrator", integrator }, { "dt", 0.01 }, { "steps", steps } };
    s["solver"] = { { "residual_tolerance", 1e-10 } };
    return s;
}

TEST(DeviceSimulation, CantileverEveryIntegratorAndDimension)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    for (int dim : { 2, 3 })
        for (const char* integrator : { "implicit_euler", "bdf2", "newmark", "static" })
            run_both(cantilever(dim, "neo_hookean", integrator, integrator == std::string("static") ? 2 : 8),
                std::to_string(dim) + "D " + integrator);
}

TEST(DeviceSimulation, ConsistentMass)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    // "mass": "consistent": the device's inertial energy, gradient and Hessian from the consistent mass
    // matrix (DeviceNewton::set_consistent_mass), every dynamic integrator, 2D and 3D.
    for (int dim : { 2, 3 })
        for (const char* integrator : { "implicit_euler", "bdf2", "newmark" }) {
            json s = cantilever(dim, "neo_hookean", integrator, 8);
            s["mass"] = "consistent";
            run_both(s, std::to_string(dim) + "D " + integrator + ", consistent mass");
        }
}

TEST(DeviceSimulation, ElasticStudies)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    // The repo's elastic example scenes (studies/101, 102) as they are, at the comparison's tolerance.
    for (const char* folder : { "101_cantilever", "102_bar_2d" }) {
        json s = json::parse(test::read_file(std::string(DIFFIPC_SOURCE_DIR) + "/studies/" + folder + "/scene.json"));
        s.erase("output");
        s["solver"]["residual_tolerance"] = 1e-10;
        run_both(s, folder);
    }
}

TEST(DeviceSimulation, EveryMaterialUnderATraction)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    for (const char* model : { "linear", "stvk", "neo_hookean", "stable_neo_hookean" })
        for (int dim : { 2, 3 }) {
            json s = cantilever(dim, model, "implicit_euler", 5);
            std::vector<double> lo(size_t(dim), -1.0), hi(size_t(dim), 2.0);
            lo[0] = hi[0] = 1.0;
            json traction = dim == 2 ? json { "2e4*t", "-1e4*t" } : json { "2e4*t", "-1e4*t", "5e3*t" };
            s["neumann"] = { { { "body", 0 }, { "region", test::region(lo, hi) }, { "traction", traction } } };
            run_both(s, std::to_string(dim) + "D " + model + " traction");
        }
}

TEST(DeviceSimulation, PrescribedStretchLiftsTheConstrainedDofs)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    // Static: the free end is pulled 20% by a prescribed displacement (lifting in every step).
    for (int dim : { 2, 3 }) {
        json s = cantilever(dim, "stable_neo_hookean", "static", 3);
        s.erase("gravity");
        std::vector<double> lo(size_t(dim), -1.0), hi(size_t(dim), 2.0);
        lo[0] = hi[0] = 1.0;
        json pull = json::array({ "0.2*t/3" });
        for (int a = 1; a < dim; ++a)
            pull.push_back(nullptr);
        s["dirichlet"].push_back({ { "body", 0 }, { "region", test::region(lo, hi) }, { "displacement", pull } });
        run_both(s, std::to_string(dim) + "D prescribed stretch");
    }
}

TEST(DeviceSimulation, FailedStepReportsTheCpuStatusAndKeepsTheCommittedState)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    json s = cantilever(3, "neo_hookean", "implicit_euler", 3);
    s["solver"]["max_iterations"] = 1; // one Newton iteration cannot converge this step
    s["device"] = "cpu";
    Simulator cpu(test::make_scene(s));
    cpu.run();
    s["device"] = "gpu";
    Simulator gpu(test::make_scene(s));
    const VectorXd before = gpu.positions();
    const StepStatus status = gpu.step();
    EXPECT_EQ(cpu.trajectory().final_status, StepStatus::NEWTON_EXHAUSTED);
    EXPECT_EQ(status, cpu.trajectory().final_status);
    EXPECT_EQ(gpu.trajectory().committed(), 0);
    EXPECT_EQ(gpu.current_step(), 0);
    EXPECT_EQ((gpu.positions() - before).lpNorm<Eigen::Infinity>(), 0.0); // untouched, bit for bit
}

bool request_density(const std::string& integrator) { return integrator != "static"; }

TEST(DeviceSimulation, PeriodicCellsWithoutContact)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    // A periodic cell (the CPU's periodic tests' compressed cell: G(0, 0) = -0.2 t prescribed, the other
    // diagonal components free, gravity) solved in its reduced unknowns on the device
    // (DeviceSolver::solve_periodic): the states and the macro gradients of every step against the CPU's;
    // the adjoint gradients of the two runs (the periodic adjoint solves on the CPU, from each run's states).
    for (int dim : { 2, 3 })
        for (const char* integrator : { "static", "implicit_euler" }) {
            const std::string name = std::to_string(dim) + "D periodic cell, " + integrator;
            json s = test::compressed_periodic_cell(dim, integrator);
            std::unique_ptr<Simulator> sims[2];
            ParameterGradient g[2];
            for (int k = 0; k < 2; ++k) {
                s["device"] = k == 0 ? "cpu" : "gpu";
                sims[k] = std::make_unique<Simulator>(test::make_scene(s));
                sims[k]->run();
                ASSERT_EQ(sims[k]->trajectory().final_status, StepStatus::CONVERGED)
                    << name << " " << k << ": " << sims[k]->trajectory().failure_message;
                const StateSeed seed = test::random_position_seed(*sims[k], sims[k]->trajectory().committed());
                ParameterRequest request;
                request.rest_positions = request.lame = true;
                g[k] = adjoint_gradient(*sims[k], seed, request);
            }
            const Trajectory &a = sims[0]->trajectory(), &b = sims[1]->trajectory();
            ASSERT_EQ(a.committed(), b.committed()) << name;
            double dx = 0, largest = 0, dG = 0, largest_G = 0;
            for (int k = 1; k <= a.committed(); ++k) {
                dx = std::max(dx, (a.step(k).positions - b.step(k).positions).lpNorm<Eigen::Infinity>());
                largest = std::max(largest, (a.step(k).positions - a.initial_positions).lpNorm<Eigen::Infinity>());
                dG = std::max(dG, (a.step(k).macro_gradient - b.step(k).macro_gradient).lpNorm<Eigen::Infinity>());
                largest_G = std::max(largest_G, a.step(k).macro_gradient.lpNorm<Eigen::Infinity>());
                EXPECT_LE(b.step(k).residual, s["solver"]["residual_tolerance"].get<double>()) << name << " step " << k;
            }
            const double e_shape = test::relative_difference(g[1].rest_positions, g[0].rest_positions);
            const double e_mu = test::relative_difference(g[1].mu, g[0].mu);
            std::printf("  %-32s %d steps: states within %.1e of the largest displacement %.3e m, G within %.1e of "
                        "|G| %.3f; adjoint gradient GPU run against CPU run: shape %.1e, mu %.1e\n",
                name.c_str(), a.committed(), dx / largest, largest, dG / largest_G, largest_G, e_shape, e_mu);
            EXPECT_GT(largest, 0) << name;
            EXPECT_LE(dx, RELATIVE_TOLERANCE * largest) << name;
            EXPECT_LE(dG, RELATIVE_TOLERANCE * largest_G) << name;
            EXPECT_LT(e_shape, 1e-6) << name;
            EXPECT_LT(e_mu, 1e-6) << name;
        }
}

TEST(DeviceSimulation, AdjointGradientEqualsTheCpus)
{
    DIFFIPC_SKIP_WITHOUT_GPU();
    // The adjoint systems of a GPU run are solved on the device (true Hessian, PCG to 1e-12);
    // the gradients of the same objective must match the CPU run's (direct solves) to 1e-6.
    for (int dim : { 2, 3 })
        for (const char* integrator : { "implicit_euler", "bdf2", "static", "implicit_euler consistent" }) {
            const bool consistent = std::string(integrator) == "implicit_euler consistent";
            json s = cantilever(dim, "neo_hookean", consistent ? "implicit_euler" : integrator, 4);
            if (consistent)
                s["mass"] = "consistent"; // the device's adjoint matrix with the consistent mass
            std::vector<double> lo(size_t(dim), -1.0), hi(size_t(dim), 2.0);
            lo[0] = hi[0] = 1.0;
            s["neumann"] = { { { "body", 0 }, { "region", test::region(lo, hi) },
                { "traction", dim == 2 ? json { 0, "-2e4*t" } : json { 0, "-2e4*t", 0 } } } };
            ParameterGradient g[2], multigrid;
            AdjointStatistics stats[2], multigrid_stats;
            for (int k = 0; k < 2; ++k) {
                s["device"] = k == 0 ? "cpu" : "gpu";
                Simulator sim(test::make_scene(s));
                sim.run();
                ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED);
                const int T = sim.trajectory().committed();
                const StateSeed seed = test::random_position_seed(sim, T);
                ParameterRequest request;
                request.rest_positions = request.lame = true;
                request.density = request_density(integrator);
                g[k] = adjoint_gradient(sim, seed, request, &stats[k]);
                if (k == 1) { // the same sweep preconditioned by the multigrid
                    sim.device_solver()->set_adjoint_multigrid(true);
                    multigrid = adjoint_gradient(sim, seed, request, &multigrid_stats);
                }
            }
            const std::string name = std::to_string(dim) + "D " + integrator;
            const double e_multigrid
                = std::max(test::relative_difference(multigrid.rest_positions, g[0].rest_positions),
                    test::relative_difference(multigrid.mu, g[0].mu));
            EXPECT_LT(e_multigrid, 1e-6) << name << ": the multigrid-preconditioned adjoint";
            EXPECT_EQ(multigrid_stats.factorization_time, 0.0) << name << ": the multigrid run fell back to the CPU";
            EXPECT_GT(multigrid_stats.device_pcg_iterations, 0) << name;
            const double e_shape = test::relative_difference(g[1].rest_positions, g[0].rest_positions);
            const double e_mu = test::relative_difference(g[1].mu, g[0].mu);
            const double e_lambda = test::relative_difference(g[1].lambda, g[0].lambda);
            std::printf("  %-20s adjoint gradient GPU against CPU: shape %.1e, mu %.1e, lambda %.1e relative; "
                        "adjoint solve time CPU %.4f s (factorization %.4f), GPU %.4f s\n",
                name.c_str(), e_shape, e_mu, e_lambda, stats[0].solve_time + stats[0].factorization_time,
                stats[0].factorization_time, stats[1].solve_time + stats[1].factorization_time);
            EXPECT_GT(g[0].rest_positions.norm(), 0) << name;
            EXPECT_LT(e_shape, 1e-6) << name;
            EXPECT_LT(e_mu, 1e-6) << name;
            EXPECT_LT(e_lambda, 1e-6) << name;
            if (request_density(integrator))
                EXPECT_LT(test::relative_difference(g[1].density, g[0].density), 1e-6) << name;
            EXPECT_EQ(stats[1].factorization_time, 0.0) << name << ": the GPU run fell back to the CPU factorization";
        }
}

} // namespace
