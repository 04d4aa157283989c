// `diffipc bench --suite gpu`: the same elastic boxes and contact scenes (a slab dropped on a
// clamped base) stepped by the CPU solver (all usable cores) and by the GPU path (scene "device":
// "gpu"), side by side in one run; per step and per phase, and the largest difference of the final
// states; and the adjoint gradient of a stress p-norm on each path, against its forward run.
// Prints figures; asserts nothing (docs/performance.md).

#include "cli/bench.hpp"
#include "cli/bench_scenes.hpp"

#include "adjoint/adjoint.hpp"
#include "forward/common/threads.hpp"
#include "forward/common/timer.hpp"
#include "forward/scene/scene.hpp"
#include "forward/simulation/device_solver.hpp"
#include "forward/simulation/simulator.hpp"
#include "objectives/objective_json.hpp"

#include <algorithm>
#include <cstdio>
#include <string>

namespace diffipc {

namespace {

    struct Run {
        int steps = 0, iterations = 0, line_search_cuts = 0, friction_solves = 0;
        double wall = 0;
        PhaseTimes phases;
        StepStatus status = StepStatus::CONVERGED;
        VectorXd x;
        DeviceSolver::ContactProfile contact; // GPU runs with contact: after the warm-up
        long pcg_iterations = 0;
        // The adjoint: dJ/d(mu, lambda) of a stress p-norm at the final time over the whole run,
        // against the whole forward run's wall time (warm-up included).
        double forward_total = 0, adjoint = 0;
        double objective_seed = 0; ///< of adjoint: the objective's dJ/dx and explicit partials
        AdjointStatistics adjoint_stats;
        // GPU runs: the adjoint sweep again with the multigrid (the seed not counted), with the plan and
        // with the plan reused; their statistics and the gradients' largest relative difference from
        // block-Jacobi's.
        double multigrid_sweep[2] = { 0, 0 }, multigrid_difference = 0;
        AdjointStatistics multigrid_stats[2];
        VectorXd gradient;
    };

    /// Steps 2.. of the scene (the first is a warm-up: the CPU's symbolic analysis, the GPU's
    /// module loading and allocations), on `device`.
    /// @param kappa a fixed barrier stiffness for a contact scene (> 0; the adjoint needs one), or 0
    Run measure(nlohmann::json scene, const std::string& device, const std::string& name, double kappa = 0)
    {
        scene["device"] = device;
        SimulationParameters parameters;
        parameters.kappa = kappa;
        Simulator sim(parse_scene(scene, ".", name), parameters);
        Run r;
        if ((r.status = sim.step()) != StepStatus::CONVERGED)
            return r;
        const Trajectory warm = sim.trajectory();
        const DeviceSolver* solver = sim.device_solver();
        const DeviceSolver::ContactProfile warm_contact
            = solver ? solver->contact_profile() : DeviceSolver::ContactProfile {};
        const long warm_pcg = solver ? solver->total_pcg_iterations() : 0;
        while (sim.steps_done() < sim.scene().time.steps)
            if ((r.status = sim.step()) != StepStatus::CONVERGED)
                break;
        const Trajectory& t = sim.trajectory();
        r.steps = int(t.steps.size() - warm.steps.size());
        r.iterations = t.newton_iterations - warm.newton_iterations;
        r.wall = t.wall_time - warm.wall_time;
        r.phases = t.phases - warm.phases;
        r.line_search_cuts = t.totals.line_search_cuts - warm.totals.line_search_cuts;
        for (size_t k = warm.steps.size(); k < t.steps.size(); ++k)
            r.friction_solves += t.steps[k].friction_iterations;
        r.x = sim.positions();
        r.forward_total = t.wall_time;
        if (r.status == StepStatus::CONVERGED) {
            const nlohmann::json spec = { { "type", "stress_norm" }, { "p", 8 }, { "time", "final" } };
            const auto objective = parse_objective(spec, "objective", sim);
            ParameterRequest request;
            request.lame = true;
            Timer timer;
            StateSeed seed;
            seed.resize(int(t.steps.size()));
            objective->add_gradient(sim, t, request, 1.0, seed);
            r.objective_seed = timer.seconds();
            const ParameterGradient g = adjoint_gradient(sim, seed, request, &r.adjoint_stats);
            r.adjoint = timer.seconds();
            r.gradient.resize(g.mu.size() + g.lambda.size());
            r.gradient << g.mu, g.lambda;
            if (DeviceSolver* device = sim.device_solver()) {
                // The same sweep with the multigrid instead of block-Jacobi, twice: the first plans the
                // hierarchy (once per run), the second reuses the plan.
                device->set_adjoint_multigrid(true);
                for (int k = 0; k < 2; ++k) {
                    Timer again;
                    const ParameterGradient m = adjoint_gradient(sim, seed, request, &r.multigrid_stats[k]);
                    r.multigrid_sweep[k] = again.seconds();
                    VectorXd gm(m.mu.size() + m.lambda.size());
                    gm << m.mu, m.lambda;
                    r.multigrid_difference
                        = std::max(r.multigrid_difference, (gm - r.gradient).norm() / r.gradient.norm());
                }
                device->set_adjoint_multigrid(false);
            }
        }
        if (solver) {
            const DeviceSolver::ContactProfile c = solver->contact_profile();
            r.contact.active_sets = c.active_sets - warm_contact.active_sets;
            r.contact.energies = c.energies - warm_contact.energies;
            r.contact.active_set_count = c.active_set_count - warm_contact.active_set_count;
            r.contact.energy_count = c.energy_count - warm_contact.energy_count;
            r.contact.max_active = c.max_active;
            r.contact.contact_sets = c.contact_sets - warm_contact.contact_sets;
            r.contact.contact_set_count = c.contact_set_count - warm_contact.contact_set_count;
            r.contact.friction_uploads = c.friction_uploads - warm_contact.friction_uploads;
            r.contact.friction_upload_count = c.friction_upload_count - warm_contact.friction_upload_count;
            r.pcg_iterations = solver->total_pcg_iterations() - warm_pcg;
        }
        return r;
    }

    void print(const char* device, const Run& r)
    {
        const PhaseTimes& p = r.phases;
        const double per = r.steps > 0 ? 1.0 / r.steps : 0.0;
        std::printf("  %-4s %-9s %2d steps, %5.1f Newton it/step, %9.4f s/step: assembly %.4f, factorization %.4f, "
                    "solve %.4f, line search %.4f\n",
            device, to_string(r.status).c_str(), r.steps, r.steps ? double(r.iterations) / r.steps : 0.0, r.wall * per,
            p.assembly * per, p.factorization * per, p.solve * per, p.line_search * per);
        if (p.broad_phase + p.ccd + p.barrier > 0)
            std::printf("       of which contact: broad phase %.4f, CCD %.4f, barrier %.4f s/step\n",
                p.broad_phase * per, p.ccd * per, p.barrier * per);
        // Outside the Newton phases: the step's set-up, the friction lagging (and its residual), the records.
        std::printf("       outside the Newton phases %.4f s/step; %.1f line-search cuts/step",
            (r.wall - p.assembly - p.factorization - p.solve - p.line_search) * per, r.line_search_cuts * per);
        if (r.friction_solves > 0)
            std::printf("; %.1f friction-lagging solves/step", r.friction_solves * per);
        std::printf("\n");
        if (r.pcg_iterations > 0)
            std::printf("       PCG %.0f iterations/step\n", double(r.pcg_iterations) * per);
        const DeviceSolver::ContactProfile& c = r.contact;
        if (r.adjoint > 0) {
            const AdjointStatistics& a = r.adjoint_stats;
            std::printf("       adjoint dJ/d(mu, lambda) of a stress p-norm: %.4f s = %.1f%% of the whole forward run "
                        "(%.4f s); assembly %.4f (parameter derivatives %.4f), factorization %.4f, solve %.4f\n",
                r.adjoint, 100 * r.adjoint / r.forward_total, r.forward_total, a.assembly_time, a.parameter_time,
                a.factorization_time, a.solve_time);
            // The profile of the adjoint gradient's wall time: what the phases above leave out.
            std::printf("       of the adjoint: objective seed %.4f, sweep set-up and step problems %.4f, the rest "
                        "(sweep vectors, history) %.4f; %d systems, %ld device PCG iterations\n",
                r.objective_seed, a.setup_time,
                r.adjoint - r.objective_seed - a.setup_time - a.assembly_time - a.factorization_time - a.solve_time,
                a.steps, a.device_pcg_iterations);
            if (r.multigrid_sweep[0] > 0) {
                const AdjointStatistics* m = r.multigrid_stats;
                std::printf(
                    "       the sweep with the multigrid instead of block-Jacobi: %.4f s with its plan (solve %.4f), "
                    "%.4f s reusing it (solve %.4f), against %.4f s (solve %.4f); device PCG iterations %ld, "
                    "%ld against %ld; gradients within %.1e\n",
                    r.multigrid_sweep[0], m[0].solve_time, r.multigrid_sweep[1], m[1].solve_time,
                    r.adjoint - r.objective_seed, a.solve_time, m[0].device_pcg_iterations, m[1].device_pcg_iterations,
                    a.device_pcg_iterations, r.multigrid_difference);
            }
        }
        if (c.active_set_count > 0)
            std::printf("       of the barrier: %.1f active-set rebuilds/step (%.2f ms each, up to %d pairs), %.1f "
                        "energies/step (%.2f ms each)\n",
                double(c.active_set_count) * per, 1e3 * c.active_sets / double(c.active_set_count), c.max_active,
                double(c.energy_count) * per, c.energy_count ? 1e3 * c.energies / double(c.energy_count) : 0.0);
        if (c.contact_set_count > 0 || c.friction_upload_count > 0)
            std::printf(
                "       outside the Newton phases: %.1f active sets for the records and the lagging/step (%.2f ms "
                "each), %.1f friction uploads/step (%.2f ms each)\n",
                double(c.contact_set_count) * per,
                c.contact_set_count ? 1e3 * c.contact_sets / c.contact_set_count : 0.0,
                double(c.friction_upload_count) * per,
                c.friction_upload_count ? 1e3 * c.friction_uploads / c.friction_upload_count : 0.0);
    }

} // namespace

int run_gpu_bench(const BenchOptions& options)
{
    std::string why;
    if (!DeviceSolver::available(&why)) {
        std::printf("bench --suite gpu: no usable GPU: %s\n", why.c_str());
        return 1;
    }
    const bool full = options.size == "full";
    const auto wanted = [&](const std::string& s) {
        return options.scenes.empty() || ("," + options.scenes + ",").find("," + s + ",") != std::string::npos;
    };
    struct Box {
        std::string key, name;
        std::vector<int> cells;
    };
    // 6 tetrahedra per cube: 50,400, 202,752 and 998,400 tetrahedra (small: 2,160 and 5,880).
    std::vector<Box> boxes = full
        ? std::vector<Box> { { "50k", "3d-box-50k", { 40, 14, 15 } }, { "200k", "3d-box-200k", { 64, 22, 24 } },
              { "1m", "3d-box-1m", { 80, 40, 52 } } }
        : std::vector<Box> { { "50k", "3d-box-2k", { 12, 5, 6 } }, { "200k", "3d-box-6k", { 20, 7, 7 } } };
    ensure_threads_configured();
    std::printf("diffipc bench --suite gpu (%s): the CPU path (%s) against the GPU path (%s); %d steps per scene, "
                "the first a warm-up\n",
        options.size.c_str(), describe(thread_config()).c_str(), DeviceSolver::describe_device().c_str(),
        options.steps);
    int failures = 0;
    // One scene on both paths, side by side. A contact scene's kappa is fixed (the adjoint needs it)
    // at the value the adaptive rule gives its first step on the GPU.
    const auto compare = [&](const nlohmann::json& scene, const std::string& name) {
        Simulator probe(parse_scene(scene, ".", name));
        std::printf("\n%s: %ld vertices, %ld tetrahedra, %ld dofs\n", name.c_str(), long(probe.mesh().num_vertices()),
            long(probe.mesh().num_elements()), long(probe.mesh().num_dofs()));
        double kappa = 0;
        if (probe.contact()) {
            nlohmann::json first = scene;
            first["device"] = "gpu";
            Simulator nominal(parse_scene(first, ".", name));
            if (nominal.step() == StepStatus::CONVERGED)
                kappa = nominal.trajectory().steps.back().kappa;
            std::printf("  kappa fixed at %.4g (the adaptive rule's after the first step)\n", kappa);
        }
        const Run cpu = measure(scene, "cpu", name, kappa);
        print("cpu", cpu);
        const Run gpu = measure(scene, "gpu", name, kappa);
        print("gpu", gpu);
        if (cpu.steps > 0 && gpu.steps > 0) {
            const VectorXd X = probe.positions();
            std::printf("  GPU / CPU: %.1fx faster per step; final states differ by %.2e m (largest displacement "
                        "%.3e m)\n",
                (cpu.wall / cpu.steps) / (gpu.wall / gpu.steps), (cpu.x - gpu.x).lpNorm<Eigen::Infinity>(),
                (cpu.x - X).lpNorm<Eigen::Infinity>());
            if (cpu.gradient.size() > 0 && gpu.gradient.size() == cpu.gradient.size())
                std::printf("  adjoint gradients differ by %.2e relative (GPU adjoint / CPU adjoint time %.2f)\n",
                    (gpu.gradient - cpu.gradient).norm() / cpu.gradient.norm(), gpu.adjoint / cpu.adjoint);
        }
        failures += cpu.status != StepStatus::CONVERGED || gpu.status != StepStatus::CONVERGED;
    };
    for (const Box& b : boxes)
        if (wanted(b.key))
            compare(beam(3, "neo_hookean", b.cells, { 4.0, 1.4, 1.5 }, options.steps), b.name);
    // The contact scene: a slab dropped on a clamped base (contact from the first step), frictionless unless
    // --friction is given.
    struct Slabs {
        std::string key, name;
        std::vector<int> base, slab;
    };
    // 6 tetrahedra per cube: 52,704, 198,000 and 966,000 tetrahedra (small: 2,208 and 6,048).
    const std::vector<Slabs> slabs = full
        ? std::vector<Slabs> { { "contact-50k", "contact-slabs-50k", { 36, 4, 36 }, { 30, 4, 30 } },
              { "contact-200k", "contact-slabs-200k", { 60, 5, 60 }, { 50, 6, 50 } },
              { "contact-1m", "contact-slabs-1m", { 100, 8, 100 }, { 90, 10, 90 } } }
        : std::vector<Slabs> { { "contact-50k", "contact-slabs-2k", { 8, 2, 8 }, { 8, 2, 8 } },
              { "contact-200k", "contact-slabs-6k", { 14, 2, 14 }, { 12, 3, 12 } } };
    // --friction MU: the slabs with lagged friction, lagged once per step (the adjoint differentiates that).
    for (const Slabs& s : slabs)
        if (wanted(s.key)) {
            nlohmann::json scene = contact_slabs(s.base, s.slab, options.steps, options.friction);
            if (options.friction > 0)
                scene["friction"]["iterations"] = 1;
            compare(scene, options.friction > 0 ? s.name + "-friction" : s.name);
        }
    return failures == 0 ? 0 : 2;
}

} // namespace diffipc
