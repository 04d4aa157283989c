// Fixed benchmark scenes. Prints figures; asserts nothing (see docs/performance.md).

#include "cli/bench.hpp"

#include "forward/common/timer.hpp"
#include "forward/scene/scene.hpp"
#include "forward/simulation/simulator.hpp"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <thread>

namespace diffipc {

namespace {

    struct BenchScene {
        std::string name;
        nlohmann::json scene;
    };

    nlohmann::json beam(int dim, const std::string& model, std::vector<int> cells, std::vector<double> extent,
        int steps, double E = 1e6, double dt = 0.01)
    {
        nlohmann::json s;
        s["dimension"] = dim;
        std::vector<double> lo(size_t(dim), 0.0);
        s["bodies"] = { { { "name", "beam" },
            { "mesh", { { "box", { { "min", lo }, { "max", extent }, { "cells", cells } } } } },
            { "material", { { "model", model }, { "E", E }, { "nu", 0.3 }, { "density", 1000 } } } } };
        std::vector<double> g(size_t(dim), 0.0);
        g[1] = -9.81;
        s["gravity"] = g;
        std::vector<double> rmin(size_t(dim), -1.0), rmax(size_t(dim), 10.0);
        rmin[0] = -1e-9;
        rmax[0] = 1e-9;
        std::vector<nlohmann::json> zero(size_t(dim), 0);
        s["dirichlet"]
            = { { { "body", "beam" }, { "region", { { "min", rmin }, { "max", rmax } } }, { "displacement", zero } } };
        s["time"] = { { "integrator", "implicit_euler" }, { "dt", dt }, { "steps", steps } };
        s["solver"] = { { "residual_tolerance", 1e-6 } };
        return s;
    }

} // namespace

int run_bench(const BenchOptions& options)
{
    const bool full = options.size == "full";
    std::vector<BenchScene> scenes;
    if (full) {
        // 40 x 14 x 15 cubes, 6 tets each: 50,400 tetrahedra.
        scenes.push_back(
            { "3d-beam-50k-neo_hookean", beam(3, "neo_hookean", { 40, 14, 15 }, { 4.0, 1.4, 1.5 }, options.steps) });
        // Soft and with large steps: large rotations, many elements need PSD projection.
        scenes.push_back({ "3d-beam-50k-neo_hookean-large-deformation",
            beam(3, "neo_hookean", { 40, 14, 15 }, { 4.0, 1.4, 1.5 }, options.steps, 2e4, 0.1) });
        scenes.push_back(
            { "2d-beam-20k-neo_hookean", beam(2, "neo_hookean", { 200, 50 }, { 4.0, 1.0 }, options.steps) });
    } else {
        scenes.push_back(
            { "3d-beam-2k-neo_hookean", beam(3, "neo_hookean", { 12, 5, 6 }, { 4.0, 1.4, 1.5 }, options.steps) });
        scenes.push_back({ "2d-beam-2k-neo_hookean", beam(2, "neo_hookean", { 40, 25 }, { 4.0, 1.0 }, options.steps) });
    }
    std::printf("diffipc bench (%s), %u hardware threads\n", options.size.c_str(), std::thread::hardware_concurrency());
    for (const auto& b : scenes) {
        Simulator sim(parse_scene(b.scene, ".", b.name));
        std::printf("\n%s: %ld vertices, %ld elements, %ld dofs, %d steps (first is warm-up: symbolic analysis)\n",
            b.name.c_str(), long(sim.mesh().num_vertices()), long(sim.mesh().num_elements()),
            long(sim.mesh().num_dofs()), options.steps);
        if (sim.step() != StepStatus::CONVERGED) {
            std::printf("  warm-up step failed: %s\n", sim.trajectory().failure_message.c_str());
            continue;
        }
        const PhaseTimes warm = sim.trajectory().phases;
        const int warm_iterations = sim.trajectory().newton_iterations;
        const double warm_wall = sim.trajectory().wall_time;
        sim.run();
        const Trajectory& tr = sim.trajectory();
        PhaseTimes p = tr.phases;
        p.assembly -= warm.assembly;
        p.factorization -= warm.factorization;
        p.solve -= warm.solve;
        p.line_search -= warm.line_search;
        const int iterations = tr.newton_iterations - warm_iterations;
        const int steps = int(tr.steps.size()) - 1;
        const double wall = tr.wall_time - warm_wall;
        if (iterations <= 0 || steps <= 0) {
            std::printf("  status %s: nothing measured\n", to_string(tr.final_status).c_str());
            continue;
        }
        const double per_iteration = wall / iterations;
        const double factorization = p.factorization / iterations;
        std::printf("  status %s, %d measured steps, %d Newton iterations\n", to_string(tr.final_status).c_str(), steps,
            iterations);
        std::printf("  per step:            %8.3f s\n", wall / steps);
        std::printf("  per Newton iteration: %7.3f s\n", per_iteration);
        std::printf("    assembly           %8.4f s  (%4.1f%%)\n", p.assembly / iterations, 100 * p.assembly / wall);
        std::printf("    factorization      %8.4f s  (%4.1f%%)\n", factorization, 100 * p.factorization / wall);
        std::printf("    solve              %8.4f s  (%4.1f%%)\n", p.solve / iterations, 100 * p.solve / wall);
        std::printf(
            "    line search        %8.4f s  (%4.1f%%)\n", p.line_search / iterations, 100 * p.line_search / wall);
        std::printf("  ratio (Newton iteration) / (numeric factorization): %.2f\n", per_iteration / factorization);
        std::printf("  ratio (assembly + line search) / (factorization):   %.2f\n",
            (p.assembly + p.line_search) / p.factorization);
    }
    return 0;
}

} // namespace diffipc
