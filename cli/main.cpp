// diffipc command-line interface: simulate, validate, check, bench, gradcheck, optimize, study.
// Exit codes: 0 success, 1 bad input (one line naming the field or file),
// 2 a simulation step failed (outputs of the committed steps are still written; check: a state is invalid),
// 3 internal error, 4 gradcheck: a direction failed, 130 / 143 simulate or optimize stopped by
// SIGINT / SIGTERM (committed steps or iterations written; simulate's summary status INTERRUPTED).

#include "adjoint/adjoint.hpp"
#include "cli/bench.hpp"
#include "cli/check.hpp"
#include "cli/distributed_run.hpp"
#include "cli/gradcheck.hpp"
#include "cli/optimize.hpp"
#include "cli/simulate.hpp"
#include "cli/study.hpp"
#include "cli/sweep.hpp"
#include "forward/common/error.hpp"
#include "forward/common/threads.hpp"
#include "forward/io/output.hpp"
#include "forward/scene/json_field.hpp"
#include "forward/scene/json_input.hpp"
#include "forward/scene/scene.hpp"
#include "forward/simulation/device_solver.hpp"
#include "forward/simulation/simulator.hpp"
#include "shape_opt/optimizer/optimizer_json.hpp"
#include "shape_opt/reduced_functional.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <filesystem>
#include <iostream>

namespace fs = std::filesystem;
using namespace diffipc;

namespace {

/// The one-line description of a valid scene (validate's output).
std::string scene_line(const Scene& scene)
{
    char text[256];
    std::snprintf(text, sizeof text, "valid %dD scene, %zu bodies, %ld vertices, %ld elements, %s, %d steps of %g s",
        scene.dim, scene.bodies.size(), long(scene.mesh.num_vertices()), long(scene.mesh.num_elements()),
        to_string(scene.time.integrator).c_str(), scene.time.steps, scene.time.dt);
    return text;
}

/// Every check simulate makes before its first step: the simulator's own (contact settings
/// against the geometry, masses, materials) and the initial state.
void check_initial_state(const Scene& scene, const std::string& name)
{
    const std::string problem = open_simulator(scene, name)->state_problem();
    if (!problem.empty())
        throw InputError(name, "the initial state is invalid: " + problem);
}

/// A problem file (docs/problem_format.md) rather than a scene: it names its scene(s) or has
/// parameters, which every problem must and no scene may. Before, validate read a problem as a
/// scene and refused its first problem key ("gradcheck: unknown field").
bool is_problem_document(const nlohmann::json& document)
{
    return document.is_object()
        && (document.contains("scene") || document.contains("scenes") || document.contains("parameters"));
}

/// validate for a problem file: what gradcheck and optimize read before their first evaluation
/// (every load case's scene, objective and initial state, the parameters and their maps, the
/// constraints, the gradcheck, checkpointing and remesh settings, the optimizer's settings).
int validate_problem(const nlohmann::json& document, const std::string& path)
{
    const ReducedFunctional rf(document, fs::path(path).parent_path().string(), path);
    const std::string optimizer = document.contains("optimizer")
        ? "optimizer " + to_string(parse_optimizer_settings(JsonField(rf.optimizer_spec(), "optimizer")).algorithm)
        : std::string("no optimizer (gradcheck only)");
    const nlohmann::json& doc = rf.document();
    for (size_t c = 0; c < rf.load_cases(); ++c) {
        const std::string field = doc.contains("scenes") ? "scenes[" + std::to_string(c) + "].scene" : "scene";
        const Scene& scene = rf.scene(c);
        check_initial_state(scene, scene.source.empty() ? field : scene.source);
    }
    std::string layout;
    for (const auto& [name, size] : rf.layout())
        layout += (layout.empty() ? "" : ", ") + name + " x " + std::to_string(size);
    std::printf("%s: valid problem, %zu load case%s, %ld parameters (%s), %ld design variables, %zu constraint%s, %s\n",
        path.c_str(), rf.load_cases(), rf.load_cases() == 1 ? "" : "s", long(rf.size()), layout.c_str(),
        long(rf.design_size()), rf.constraints().size(), rf.constraints().size() == 1 ? "" : "s", optimizer.c_str());
    for (size_t c = 0; c < rf.load_cases(); ++c) {
        const nlohmann::json& jc = doc.contains("scenes") ? doc["scenes"][c] : doc;
        const Scene& scene = rf.scene(c);
        const std::string objective = jc["objective"].is_object() && jc["objective"].contains("type")
            ? jc["objective"]["type"].dump()
            : std::string("?");
        std::printf("  load case %zu: %s: %s; objective %s\n", c,
            scene.source.empty() ? "inline scene" : scene.source.c_str(), scene_line(scene).c_str(), objective.c_str());
    }
    return 0;
}

int validate(const std::string& path)
{
    const nlohmann::json document = parse_json_text(read_input_file(path, "scene or problem file"), path);
    if (is_problem_document(document))
        return validate_problem(document, path);
    const Scene scene = load_scene(document, path);
    check_initial_state(scene, path);
    std::printf("%s: %s\n", path.c_str(), scene_line(scene).c_str());
    return 0;
}

std::string version_text()
{
    try {
        ensure_threads_configured();
    } catch (const InputError& e) {
        return std::string("diffipc " DIFFIPC_VERSION "\ndiffipc: error: ") + e.what() + "\n";
    }
    std::string why;
    const std::string gpu = DeviceSolver::available(&why)
        ? DeviceSolver::describe_device() + " (\"device\": \"gpu\" runs there)"
        : "none usable: " + why + " (\"device\": \"gpu\" is refused)";
#ifdef DIFFIPC_HAVE_MPI
    const std::string mpi
        = "built with MPI (mpirun -n N diffipc optimize|gradcheck spreads the load cases over N ranks)";
#else
    const std::string mpi = "not built (configure with -DDIFFIPC_MPI=ON and libopenmpi-dev to run over ranks)";
#endif
    return "diffipc " DIFFIPC_VERSION "\n" + describe(thread_config()) + "mpi: " + mpi + "\ngpu: " + gpu + "\n";
}

/// "rank N: " for a rank > 0 of an MPI job, else "".
std::string rank_prefix(const DistributedRun* distributed)
{
    return distributed && distributed->rank() > 0 ? "rank " + std::to_string(distributed->rank()) + ": " : "";
}

} // namespace

int main(int argc, char** argv)
{
    // Before anything else: libgomp must see OMP_WAIT_POLICY when it is loaded (threads.hpp).
    prepare_process_environment(argv);
    // Under mpirun (a build with MPI): after the re-execution above, before anything else.
    std::unique_ptr<DistributedRun> distributed;
    try {
        distributed = DistributedRun::start(&argc, &argv);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "diffipc: MPI: %s\n", e.what());
        return 3;
    }
    const bool serving = distributed && distributed->rank() > 0;

    CLI::App app { "diffipc: differentiable IPC elastodynamics" };
    app.require_subcommand(1);
    app.fallthrough();
    app.set_version_flag("--version", version_text, "Print the version and the thread configuration");
    int threads = -1;
    app.add_option("--threads", threads,
           "threads for TBB, OpenBLAS and OpenMP (default: DIFFIPC_THREADS, else the file's \"threads\", else the "
           "cores this process may use)")
        ->check(CLI::Range(1, 4096));
    auto* info_cmd = app.add_subcommand(
        "info", "Print the version, the effective thread configuration and the GPU (if one is usable)");

    SimulateOptions sim_options;
    auto* sim_cmd
        = app.add_subcommand("simulate", "Run a scene; writes trajectory.h5, summary.json and optional VTU files");
    sim_cmd->add_option(
        "scene", sim_options.scene_path, "scene file (JSON); with --restart, default: the one the run was for");
    sim_cmd->add_option("--restart", sim_options.restart,
        "continue the run in this output directory from the last committed step of its trajectory.h5");
    sim_cmd->add_option("-o,--output", sim_options.out_dir, "output directory (default: the scene's output.directory)");
    sim_cmd
        ->add_option(
            "--vtu-every", sim_options.vtu_every, "write a VTU frame every N steps (0: none; default: the scene's)")
        ->check(CLI::Range(0, 1 << 30));
    sim_cmd->add_option("--steps", sim_options.steps, "time steps to take, replacing the scene's time.steps")
        ->check(CLI::Range(1, 1 << 30));
    sim_cmd->add_option("--device", sim_options.device,
        "cpu | gpu: where the Newton solves run, replacing the scene's \"device\" (gpu: elastic scenes, "
        "barrier and penalty contact, lagged friction, periodic cells, with contact across the boundary but no "
        "friction across it; docs/scene_format.md "
        "\"Device\")");
    sim_cmd->add_flag("-q,--quiet", sim_options.quiet, "no progress output");

    StudyOptions study_options;
    auto* study_cmd = app.add_subcommand(
        "study", "Run a study of studies/ (its run.py, with this build): its figures, tables and CSV go to its folder");
    study_cmd->add_option("name", study_options.name, "the study's folder or number, e.g. 502");
    study_cmd->add_flag("--full", study_options.full, "the study's full sweep (slower)");
    study_cmd->add_flag("--list", study_options.list, "list the studies that can be run");

    std::string validate_path;
    auto* val_cmd = app.add_subcommand("validate",
        "Check a scene or problem file (with its scenes, objectives and parameters) and report what it contains");
    val_cmd->add_option("file", validate_path, "scene or problem file (JSON)")->required();

    std::string check_dir, check_scene;
    bool check_quiet = false;
    auto* check_cmd = app.add_subcommand("check",
        "Check every committed state of a run (its trajectory.h5) for inverted elements, intersections and "
        "containment by exact tests independent of the solver's");
    check_cmd->add_option("run", check_dir, "the run's output directory")->required();
    check_cmd->add_option("--scene", check_scene, "the scene of the run (default: the one its trajectory names)");
    check_cmd->add_flag("-q,--quiet", check_quiet, "print only invalid states and the total");

    BenchOptions bench_options;
    auto* bench_cmd = app.add_subcommand("bench", "Run the fixed benchmark scenes and print per-phase timings");
    bench_cmd->add_option("--size", bench_options.size, "small | full")->check(CLI::IsMember({ "small", "full" }));
    bench_cmd->add_option("--steps", bench_options.steps, "time steps per scene (the first is a warm-up)");
    bench_cmd->add_option("--suite", bench_options.suite, "forward | contact | scenes | adjoint | scaling | gpu")
        ->check(CLI::IsMember({ "forward", "contact", "scenes", "adjoint", "scaling", "gpu" }));
    bench_cmd
        ->add_option("--thread-counts", bench_options.thread_counts,
            "scaling suite: thread counts, comma-separated (default 1, 2, 4, ... the usable cores)")
        ->delimiter(',')
        ->check(CLI::Range(1, 4096));
    bench_cmd->add_option("--scenes", bench_options.scenes,
        "scaling suite: any of 50k,200k,contact,adjoint,factor; gpu suite: any of "
        "50k,200k,1m,contact-50k,contact-200k,contact-1m (default: all)");
    bench_cmd->add_option("--source-dir", bench_options.source_dir, "repository root, where studies/ lives");
    bench_cmd
        ->add_option("--friction", bench_options.friction,
            "contact and gpu suites: friction coefficient of the contact slabs (0: none)")
        ->check(CLI::Range(0.0, 10.0));

    std::string problem_path;
    int directions = 0;
    auto* grad_cmd = app.add_subcommand(
        "gradcheck", "Adjoint gradient of a problem file against finite differences (Taylor table)");
    grad_cmd->add_option("problem", problem_path, "problem file (JSON)")->required();
    std::string grad_device;
    grad_cmd->add_option("--device", grad_device,
        "cpu | gpu: where the load cases' simulations and adjoint solves run, replacing the scenes' \"device\"");
    grad_cmd->add_option("--directions", directions, "random directions (default: the file's, else 2)")
        ->check(CLI::Range(1, 1 << 20));

    SweepOptions sweep_options;
    auto* sweep_cmd = app.add_subcommand("sweep",
        "Run a problem or scene at every point of a sweep file (a grid or a list of parameter values; "
        "docs/sweep.md): one folder per run and sweep.csv; under mpirun the runs go to the ranks");
    sweep_cmd->add_option("sweep", sweep_options.path, "sweep file (JSON)")->required();
    sweep_cmd->add_option(
        "-o,--output", sweep_options.out_dir, "output directory (default: the file's output.directory)");
    sweep_cmd->add_option("--device", sweep_options.device,
        "cpu | gpu: where the runs' simulations and adjoint solves run, replacing the scenes' \"device\"");
    sweep_cmd->add_flag("-q,--quiet", sweep_options.quiet, "no progress output");

    OptimizeOptions optimize_options;
    auto* opt_cmd = app.add_subcommand("optimize",
        "Optimize a problem file's design (docs/optimization.md); writes history.h5, history.csv, summary.json, "
        "designs.pvd and optimal_problem.json");
    opt_cmd->add_option("problem", optimize_options.problem_path,
        "problem file (JSON) with an \"optimizer\"; with --resume, default: the run's initial_problem.json");
    auto* resume_option = opt_cmd->add_option("--resume", optimize_options.resume_dir,
        "continue the stopped run in this output directory from the last iteration in its history.h5");
    opt_cmd
        ->add_option("-o,--output", optimize_options.out_dir, "output directory (default: the file's output.directory)")
        ->excludes(resume_option);
    opt_cmd
        ->add_option("--max-iterations", optimize_options.max_iterations,
            "iteration budget of the whole run, replacing the file's optimizer.max_iterations (0: none)")
        ->check(CLI::Range(0, 1 << 30));
    opt_cmd
        ->add_option("--max-seconds", optimize_options.max_seconds,
            "wall-time budget of the whole run, s, replacing the file's optimizer.max_seconds (0: none)")
        ->check(CLI::Range(0.0, 1e12));
    opt_cmd->add_option("--device", optimize_options.device,
        "cpu | gpu: where the load cases' simulations and adjoint solves run, replacing the scenes' \"device\" "
        "(give it again with --resume)");
    opt_cmd->add_flag("-q,--quiet", optimize_options.quiet, "no progress output");

    try {
        app.parse(argc, argv);
    } catch (const CLI::Error& e) {
        if (serving)
            return distributed->serve(); // rank 0 answers (help, version, a usage error) and ends the run
        if (dynamic_cast<const CLI::CallForHelp*>(&e) || dynamic_cast<const CLI::CallForAllHelp*>(&e)
            || dynamic_cast<const CLI::CallForVersion*>(&e))
            return app.exit(e);
        // A usage error is bad input like any other: exit 1, one line (and where to look).
        std::fprintf(stderr, "diffipc: error: %s (see diffipc --help)\n", e.what());
        return 1;
    }
    // The pools' threads: --threads, else DIFFIPC_THREADS, else a file's, else the cores (under mpirun: the rank's
    // share of its node's).
    const auto configure_threads = [&] {
        ensure_threads_configured();
        if (threads > 0)
            set_threads(threads, ThreadSource::EXPLICIT, "--threads");
        if (distributed)
            distributed->divide_cores();
    };
    if (distributed && *sweep_cmd)
        distributed->run_on_every_rank(); // no rank serves: rank 0 has none to stop at its end
    if (serving && !*sweep_cmd) {
        // Ranks > 0 evaluate load cases for rank 0 until it ends the run, whatever the command (but sweep, which
        // every rank runs): rank 0 runs it and reports any error, here one that rank 0 meets too.
        try {
            configure_threads();
        } catch (const std::exception&) {
        }
        return distributed->serve();
    }

    try {
        configure_threads();
        if (distributed && *sweep_cmd)
            return sweep(sweep_options, distributed->world());
        if (distributed) {
            if (!(*opt_cmd || *grad_cmd) && distributed->size() > 1)
                std::fprintf(stderr,
                    "diffipc: %d ranks: this command runs on rank 0 alone (optimize and gradcheck spread their load "
                    "cases)\n",
                    distributed->size());
            optimize_options.distribution = distributed->distribution();
        }
        if (*info_cmd) {
            std::printf("%s", version_text().c_str());
            return 0;
        }
        if (*sim_cmd)
            return simulate(sim_options);
        if (*val_cmd)
            return validate(validate_path);
        if (*check_cmd)
            return check_run(check_dir, check_scene, check_quiet);
        if (*opt_cmd) {
            if (optimize_options.problem_path.empty() && optimize_options.resume_dir.empty())
                throw InputError("problem", "a problem file is required (or --resume DIR)");
            return optimize(optimize_options);
        }
        if (*bench_cmd)
            return run_bench(bench_options);
        if (*sweep_cmd)
            return sweep(sweep_options, nullptr);
        if (*grad_cmd)
            return gradcheck(
                problem_path, directions, grad_device, distributed ? distributed->distribution() : nullptr);
        if (*study_cmd) {
            if (study_options.name.empty() && !study_options.list)
                throw InputError("study", "name a study (diffipc study --list shows them)");
            return run_study(study_options);
        }
    } catch (const InputError& e) {
        if (!serving) // a sweep's other ranks read the same input: rank 0 says it
            std::fprintf(stderr, "diffipc: error: %s\n", e.what());
        return 1;
    } catch (const AdjointError& e) {
        std::fprintf(stderr, "diffipc: %s%s\n", rank_prefix(distributed.get()).c_str(), e.what());
        return 2;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "diffipc: %sinternal error: %s\n", rank_prefix(distributed.get()).c_str(), e.what());
        return 3;
    }
    return 0;
}
