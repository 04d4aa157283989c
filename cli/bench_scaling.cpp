// `diffipc bench --suite scaling`: the same scenes with 1, 2, 4, ... threads, time per
// phase and parallel efficiency. Prints figures; asserts nothing (docs/performance.md).

#include "cli/bench.hpp"
#include "cli/bench_scenes.hpp"

#include "adjoint/adjoint.hpp"
#include "forward/common/threads.hpp"
#include "forward/common/timer.hpp"
#include "forward/scene/scene.hpp"
#include "forward/simulation/simulator.hpp"
#include "objectives/objective_json.hpp"

#include <cstdio>
#include <map>
#include <string>
#include <vector>

namespace diffipc {

namespace {

    /// One measurement: seconds per phase, per unit (a Newton iteration, a step, a gradient).
    struct Sample {
        int threads = 0;
        int units = 0; ///< Newton iterations (forward) or adjoint steps
        int newton_iterations = 0;
        int analyses = 0; ///< symbolic analyses (part of the factorization)
        std::vector<std::pair<std::string, double>> phases; ///< in print order; "total" first
    };

    double phase(const Sample& s, const std::string& name)
    {
        for (const auto& [n, v] : s.phases)
            if (n == name)
                return v;
        return 0;
    }

    /// Table: seconds per unit and phase for each thread count, then the speed-up over
    /// the first count and the parallel efficiency t(1) / (p t(p)) of every phase.
    void print_table(const std::string& title, const std::string& unit, const std::vector<Sample>& samples)
    {
        if (samples.empty())
            return;
        std::printf(
            "\n%s\n  seconds per %s:\n  %7s %6s %8s", title.c_str(), unit.c_str(), "threads", "newton", "analyses");
        for (const auto& [n, v] : samples[0].phases)
            std::printf(" %13s", n.c_str());
        std::printf("\n");
        for (const Sample& s : samples) {
            std::printf("  %7d %6d %8d", s.threads, s.newton_iterations, s.analyses);
            for (const auto& [n, v] : s.phases)
                std::printf(" %13.4f", v);
            std::printf("\n");
        }
        const Sample& base = samples[0];
        std::printf("  parallel efficiency t(%d) %d / (p t(p)) [speed-up of the total]:\n  %7s %6s", base.threads,
            base.threads, "threads", "");
        std::printf(" %8s", "");
        for (const auto& [n, v] : base.phases)
            std::printf(" %13s", n.c_str());
        std::printf("\n");
        for (const Sample& s : samples) {
            std::printf("  %7d %6s %8s", s.threads, "", "");
            for (const auto& [n, v] : s.phases) {
                const double t0 = phase(base, n);
                if (v > 0 && t0 > 0)
                    std::printf(" %12.0f%%", 100 * t0 * base.threads / (s.threads * v));
                else
                    std::printf(" %13s", "-");
            }
            std::printf("  [%.2fx]\n", phase(base, "total") / phase(s, "total"));
        }
        std::fflush(stdout);
    }

    Sample forward_sample(int threads, const Trajectory& before, const Trajectory& after, bool contact, int units)
    {
        const PhaseTimes p = after.phases - before.phases;
        Sample s;
        s.threads = threads;
        s.newton_iterations = after.newton_iterations - before.newton_iterations;
        s.units = units > 0 ? units : std::max(1, s.newton_iterations);
        const double u = s.units;
        const double wall = after.wall_time - before.wall_time;
        const double rest = wall - p.assembly - p.factorization - p.solve - p.line_search;
        s.analyses = p.analyses;
        s.phases = { { "total", wall / u }, { "assembly", p.assembly / u }, { "factorization", p.factorization / u },
            { "(analysis)", p.analysis / u }, { "solve", p.solve / u }, { "line_search", p.line_search / u },
            { "other", rest / u } };
        if (contact) {
            s.phases.push_back({ "broad_phase", p.broad_phase / u });
            s.phases.push_back({ "ccd", p.ccd / u });
            s.phases.push_back({ "barrier", p.barrier / u });
            const double non_contact = p.assembly + p.line_search - p.broad_phase - p.ccd - p.barrier;
            s.phases.push_back({ "elastic+rest", non_contact / u });
        }
        return s;
    }

    /// An elastic box: one simulator, a warm-up step (symbolic analysis), then `steps`
    /// steps per thread count (the stiff box takes 2 Newton iterations every step).
    void elastic_scaling(
        const std::string& name, const nlohmann::json& scene, const std::vector<int>& counts, int steps)
    {
        set_threads(counts.back(), ThreadSource::EXPLICIT, "bench --thread-counts");
        Simulator sim(parse_scene(scene, ".", name));
        std::printf("\n%s: %ld vertices, %ld elements, %ld dofs; warm-up step, then %d step(s) per thread count\n",
            name.c_str(), long(sim.mesh().num_vertices()), long(sim.mesh().num_elements()), long(sim.mesh().num_dofs()),
            steps);
        std::fflush(stdout);
        if (sim.step() != StepStatus::CONVERGED) {
            std::printf("  warm-up step failed: %s\n", sim.trajectory().failure_message.c_str());
            return;
        }
        std::vector<Sample> samples;
        for (int t : counts) {
            set_threads(t, ThreadSource::EXPLICIT, "bench --thread-counts");
            const Trajectory before = sim.trajectory();
            for (int k = 0; k < steps; ++k)
                if (sim.step() != StepStatus::CONVERGED) {
                    std::printf("  step failed: %s\n", sim.trajectory().failure_message.c_str());
                    return;
                }
            samples.push_back(forward_sample(t, before, sim.trajectory(), false, 0));
        }
        print_table(name, "Newton iteration", samples);
    }

    /// The contact scene: a fresh simulator per thread count runs the same steps (results do
    /// not depend on the thread count, so every run takes the same Newton iterations).
    void contact_scaling(bool full, const std::vector<int>& counts, int steps, double friction)
    {
        const nlohmann::json scene = contact_slabs(full, steps + 1, friction);
        std::vector<Sample> samples;
        std::string title;
        for (int t : counts) {
            set_threads(t, ThreadSource::EXPLICIT, "bench --thread-counts");
            Simulator sim(parse_scene(scene, ".", "contact-slabs"));
            if (title.empty()) {
                char mu[32];
                std::snprintf(mu, sizeof mu, "%g", friction);
                title = "contact-slabs (" + std::string(full ? "full" : "small") + ", friction " + mu + "): "
                    + std::to_string(sim.mesh().num_elements()) + " elements, " + std::to_string(sim.mesh().num_dofs())
                    + " dofs; warm-up step, then " + std::to_string(steps) + " step(s), fresh run per thread count";
                std::printf("\nrunning %s\n", title.c_str());
                std::fflush(stdout);
            }
            if (sim.step() != StepStatus::CONVERGED) {
                std::printf("  warm-up step failed: %s\n", sim.trajectory().failure_message.c_str());
                return;
            }
            const Trajectory before = sim.trajectory();
            for (int k = 0; k < steps; ++k)
                if (sim.step() != StepStatus::CONVERGED) {
                    std::printf("  step failed: %s\n", sim.trajectory().failure_message.c_str());
                    return;
                }
            samples.push_back(forward_sample(t, before, sim.trajectory(), true, steps));
        }
        print_table(title, "time step", samples);
    }

    /// Shape and material gradient of a stress p-norm on the contact scene (fixed kappa),
    /// the forward run once, the adjoint per thread count.
    void adjoint_scaling(bool full, const std::vector<int>& counts, int steps, double friction)
    {
        set_threads(counts.back(), ThreadSource::EXPLICIT, "bench --thread-counts");
        const Scene scene = parse_scene(contact_slabs(full, steps, friction), ".", "contact-slabs");
        SimulationParameters fixed;
        {
            Simulator nominal(scene);
            if (nominal.step() != StepStatus::CONVERGED) {
                std::printf("  nominal step failed\n");
                return;
            }
            fixed.kappa = nominal.trajectory().steps.back().kappa;
        }
        Simulator sim(scene, fixed);
        const Trajectory& tr = sim.run();
        if (tr.final_status != StepStatus::CONVERGED) {
            std::printf("  forward failed: %s\n", tr.failure_message.c_str());
            return;
        }
        const auto objective
            = parse_objective({ { "type", "stress_norm" }, { "p", 8 }, { "time", "final" } }, "objective", sim);
        ParameterRequest request;
        request.rest_positions = true;
        request.lame = true;
        std::vector<Sample> samples;
        for (int t : counts) {
            set_threads(t, ThreadSource::EXPLICIT, "bench --thread-counts");
            Timer total;
            Timer objective_timer;
            StateSeed seed;
            seed.resize(int(tr.steps.size()));
            objective->add_gradient(sim, tr, request, 1.0, seed);
            const double objective_time = objective_timer.seconds();
            AdjointStatistics st;
            adjoint_gradient(sim, seed, request, &st);
            const double wall = total.seconds();
            Sample s;
            s.threads = t;
            s.units = 1;
            s.phases = { { "total", wall }, { "objective", objective_time },
                { "hessian", st.assembly_time - st.parameter_time }, { "factorization", st.factorization_time },
                { "solve", st.solve_time }, { "parameters", st.parameter_time } };
            samples.push_back(s);
        }
        print_table("adjoint: shape + Lame gradient of a stress p-norm, contact-slabs ("
                + std::string(full ? "full" : "small") + ", " + std::to_string(steps) + " steps, kappa fixed)",
            "gradient", samples);
    }

} // namespace

int run_scaling_bench(const BenchOptions& options)
{
    const bool full = options.size == "full";
    std::vector<int> counts = options.thread_counts;
    if (counts.empty()) {
        const int usable = core_budget().usable;
        for (int t = 1; t <= usable; t *= 2)
            counts.push_back(t);
        if (counts.back() != usable)
            counts.push_back(usable);
    }
    std::printf("diffipc bench --suite scaling (%s), thread counts", options.size.c_str());
    for (int t : counts)
        std::printf(" %d", t);
    std::printf("\n%s", describe(set_threads(counts.back(), ThreadSource::EXPLICIT, "bench --thread-counts")).c_str());
    const std::string only = options.scenes;
    auto wanted = [&](const char* name) { return only.empty() || only.find(name) != std::string::npos; };
    if (wanted("50k"))
        elastic_scaling(full ? "3d-box-50k" : "3d-box-2k",
            full ? beam(3, "neo_hookean", { 40, 14, 15 }, { 4.0, 1.4, 1.5 }, 1000)
                 : beam(3, "neo_hookean", { 12, 5, 6 }, { 4.0, 1.4, 1.5 }, 1000),
            counts, options.steps);
    if (wanted("200k"))
        elastic_scaling(full ? "3d-box-200k" : "3d-box-6k",
            full ? beam(3, "neo_hookean", { 64, 22, 24 }, { 4.0, 1.4, 1.5 }, 1000)
                 : beam(3, "neo_hookean", { 20, 7, 7 }, { 4.0, 1.4, 1.5 }, 1000),
            counts, options.steps);
    if (wanted("contact"))
        contact_scaling(full, counts, options.steps, options.friction);
    if (wanted("adjoint"))
        adjoint_scaling(full, counts, options.steps, options.friction);
    if (wanted("factor"))
        factorization_comparison(full, counts, std::max(1, options.steps));
    return 0;
}

} // namespace diffipc
