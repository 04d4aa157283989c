// Fixed benchmark scenes. Prints figures; asserts nothing (see docs/performance.md).

#include "cli/bench.hpp"

#include "cli/bench_scenes.hpp"

#include "adjoint/adjoint.hpp"
#include "forward/common/timer.hpp"
#include "forward/contact/intersection.hpp"
#include "forward/scene/scene.hpp"
#include "forward/simulation/simulator.hpp"
#include "objectives/objective_json.hpp"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>

namespace diffipc {

namespace {

    struct BenchScene {
        std::string name;
        nlohmann::json scene;
    };

    int run_contact_bench(const BenchOptions& options)
    {
        const bool full = options.size == "full";
        Simulator sim(parse_scene(contact_slabs(full, options.steps, options.friction), ".", "contact-slabs"));
        std::printf(
            "contact-slabs (%s, friction %g): %ld vertices, %ld elements, %ld dofs, %d steps (first is warm-up)\n",
            options.size.c_str(), options.friction, long(sim.mesh().num_vertices()), long(sim.mesh().num_elements()),
            long(sim.mesh().num_dofs()), options.steps);
        if (sim.step() != StepStatus::CONVERGED) {
            std::printf("  warm-up step failed: %s\n", sim.trajectory().failure_message.c_str());
            return 1;
        }
        const Trajectory warm = sim.trajectory();
        while (sim.steps_done() < options.steps) {
            if (sim.step() != StepStatus::CONVERGED)
                break;
            const StepRecord& r = sim.trajectory().steps.back();
            std::printf(
                "  step %d: %d Newton iterations, %d active contacts, min distance %.3g m, kappa %.3g, %.3f s\n",
                r.index, r.newton_iterations, r.active_contacts, r.min_distance, r.kappa, r.wall_time);
        }
        const Trajectory& tr = sim.trajectory();
        const PhaseTimes p = tr.phases - warm.phases;
        const int steps = int(tr.steps.size() - warm.steps.size());
        const int iterations = tr.newton_iterations - warm.newton_iterations;
        const double wall = tr.wall_time - warm.wall_time;
        if (steps <= 0 || iterations <= 0) {
            std::printf("  status %s: nothing measured\n", to_string(tr.final_status).c_str());
            return 1;
        }
        const double contact = p.broad_phase + p.ccd + p.barrier;
        std::printf("  status %s, %d measured steps, %d Newton iterations\n", to_string(tr.final_status).c_str(), steps,
            iterations);
        std::printf("  per step:              %8.3f s\n", wall / steps);
        std::printf("    assembly (all)       %8.4f s  (%4.1f%%)\n", p.assembly / steps, 100 * p.assembly / wall);
        std::printf(
            "    factorization        %8.4f s  (%4.1f%%)\n", p.factorization / steps, 100 * p.factorization / wall);
        std::printf(
            "    of which %2d analyses %8.4f s  (%4.1f%%)\n", p.analyses, p.analysis / steps, 100 * p.analysis / wall);
        std::printf("    solve                %8.4f s  (%4.1f%%)\n", p.solve / steps, 100 * p.solve / wall);
        std::printf("    line search (all)    %8.4f s  (%4.1f%%)\n", p.line_search / steps, 100 * p.line_search / wall);
        std::printf("    of which broad phase %8.4f s  (%4.1f%%)\n", p.broad_phase / steps, 100 * p.broad_phase / wall);
        std::printf("    of which CCD         %8.4f s  (%4.1f%%)\n", p.ccd / steps, 100 * p.ccd / wall);
        std::printf("    of which barrier     %8.4f s  (%4.1f%%)\n", p.barrier / steps, 100 * p.barrier / wall);
        std::printf("  ratio (broad phase + CCD + barrier) / (factorization): %.2f\n", contact / p.factorization);
        return tr.final_status == StepStatus::CONVERGED ? 0 : 2;
    }

    /// Adjoint cost against the forward run on the contact scene: a nominal step picks
    /// the adaptive kappa, then a run with that kappa fixed (the differentiated run) is
    /// timed, then shape and material gradients of a stress p-norm of the final state.
    int run_adjoint_bench(const BenchOptions& options)
    {
        const bool full = options.size == "full";
        const Scene scene = parse_scene(contact_slabs(full, options.steps, options.friction), ".", "contact-slabs");
        SimulationParameters fixed;
        {
            Simulator nominal(scene);
            if (nominal.step() != StepStatus::CONVERGED) {
                std::printf("  nominal step failed: %s\n", nominal.trajectory().failure_message.c_str());
                return 1;
            }
            fixed.kappa = nominal.trajectory().steps.back().kappa;
        }
        Simulator sim(scene, fixed);
        std::printf("contact-slabs adjoint (%s, friction %g): %ld elements, %ld dofs, %d steps, kappa %.4g fixed\n",
            options.size.c_str(), options.friction, long(sim.mesh().num_elements()), long(sim.mesh().num_dofs()),
            options.steps, fixed.kappa);
        Timer forward_timer;
        const Trajectory& tr = sim.run();
        const double forward = forward_timer.seconds();
        if (tr.final_status != StepStatus::CONVERGED) {
            std::printf("  forward failed at step %d: %s\n", tr.failed_step, tr.failure_message.c_str());
            return 1;
        }
        size_t friction_contacts = 0;
        for (const StepRecord& r : tr.steps)
            friction_contacts += r.friction.size();
        std::printf("  forward: %.3f s (%d Newton iterations, %zu lagged friction contacts over the run)\n", forward,
            tr.newton_iterations, friction_contacts);
        const nlohmann::json spec = { { "type", "stress_norm" }, { "p", 8 }, { "time", "final" } };
        const auto objective = parse_objective(spec, "objective", sim);
        struct Case {
            const char* name;
            ParameterRequest request;
        };
        ParameterRequest shape, material;
        shape.rest_positions = true;
        material.lame = true;
        for (const Case& c : { Case { "shape (rest positions)", shape }, Case { "material (mu, lambda)", material } }) {
            Timer t;
            StateSeed seed;
            seed.resize(int(tr.steps.size()));
            objective->add_gradient(sim, tr, c.request, 1.0, seed);
            AdjointStatistics st;
            const ParameterGradient g = adjoint_gradient(sim, seed, c.request, &st);
            const double total = t.seconds();
            const double norm = g.rest_positions.norm() + g.mu.norm() + g.lambda.norm();
            std::printf("  %-24s %.3f s = %5.1f%% of the forward (assembly %.3f, factorization %.3f, solve %.3f s; "
                        "|dJ/dp| %.3e)\n",
                c.name, total, 100 * total / forward, st.assembly_time, st.factorization_time, st.solve_time, norm);
        }
        return 0;
    }

    int run_scene_bench(const BenchOptions& options)
    {
        namespace fs = std::filesystem;
        const char* names[] = { "201_ring_on_plane", "202_boxes_head_on", "203_box_squeeze", "204_ring_pile",
            "205_plate_on_sphere", "206_ring_chain" };
        int failures = 0;
        for (const char* name : names) {
            const std::string path = (fs::path(options.source_dir) / "studies" / name / "scene.json").string();
            Simulator sim(load_scene(path));
            int bad_states = 0, max_active = 0;
            double min_distance = 1e300;
            while (sim.steps_done() < sim.scene().time.steps) {
                if (sim.step() != StepStatus::CONVERGED)
                    break;
                const StepRecord& r = sim.trajectory().steps.back();
                max_active = std::max(max_active, r.active_contacts);
                min_distance = std::min(min_distance, r.min_distance);
                const Positions X = unflatten(sim.positions(), sim.scene().dim);
                bad_states += count_inverted_elements(sim.scene().mesh, X) > 0
                    || !find_intersection(sim.contact()->collision_mesh(), X, true).empty();
            }
            const Trajectory& tr = sim.trajectory();
            failures += tr.final_status != StepStatus::CONVERGED || bad_states > 0;
            std::printf("%-22s %6ld tets/tris, %4zu/%4d steps, %-9s %5d Newton it, max active %5d, min dist %.3g m, "
                        "invalid states %d, %.2f s (CCD %.2f, broad %.2f, barrier %.2f)\n",
                name, long(sim.mesh().num_elements()), tr.steps.size(), sim.scene().time.steps,
                to_string(tr.final_status).c_str(), tr.newton_iterations, max_active, min_distance, bad_states,
                tr.wall_time, tr.phases.ccd, tr.phases.broad_phase, tr.phases.barrier);
        }
        return failures == 0 ? 0 : 2;
    }

} // namespace

int run_bench(const BenchOptions& options)
{
    if (options.suite == "contact")
        return run_contact_bench(options);
    if (options.suite == "adjoint")
        return run_adjoint_bench(options);
    if (options.suite == "scenes")
        return run_scene_bench(options);
    if (options.suite == "scaling")
        return run_scaling_bench(options);
    if (options.suite == "gpu")
        return run_gpu_bench(options);
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
