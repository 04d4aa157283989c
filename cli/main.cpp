// diffipc command-line interface: simulate, validate, bench.
// Exit codes: 0 success, 1 bad input (one line naming the field or file),
// 2 a simulation step failed (outputs of the committed steps are still written),
// 3 internal error, 4 gradcheck: a direction failed, 130 / 143 simulate stopped by
// SIGINT / SIGTERM (committed steps written, summary status INTERRUPTED).

#include "adjoint/adjoint.hpp"
#include "cli/bench.hpp"
#include "cli/gradcheck.hpp"
#include "forward/common/error.hpp"
#include "forward/common/threads.hpp"
#include "forward/common/timer.hpp"
#include "forward/io/output.hpp"
#include "forward/scene/scene.hpp"
#include "forward/simulation/simulator.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>

namespace fs = std::filesystem;
using namespace diffipc;

namespace {

/// The first SIGINT or SIGTERM asks the run to stop after the current step; the handler
/// then restores the default action, so a second one ends the process at once (the
/// trajectory keeps every step up to its last flush).
volatile std::sig_atomic_t g_stop_signal = 0;

extern "C" void on_stop_signal(int signal)
{
    g_stop_signal = signal;
    std::signal(signal, SIG_DFL);
}

/// Exit code of a run stopped by `signal`: 128 + the signal number, as shells report it.
int interrupted_exit_code(int signal) { return 128 + signal; }

int simulate(std::string scene_path, std::string out_dir, int vtu_every, bool quiet, const std::string& restart)
{
    // --restart DIR: the run in DIR goes on from its last committed step in trajectory.h5.
    std::unique_ptr<StoredTrajectory> stored;
    if (!restart.empty()) {
        if (!out_dir.empty() && fs::path(out_dir) != fs::path(restart))
            throw InputError("--restart", "continues the run in its own directory; leave -o out");
        out_dir = restart;
        stored = std::make_unique<StoredTrajectory>(read_trajectory((fs::path(restart) / "trajectory.h5").string()));
        if (scene_path.empty())
            scene_path = stored->scene;
        if (scene_path.empty())
            throw InputError("--restart", "the trajectory does not name its scene: give the scene file");
    }
    if (scene_path.empty())
        throw InputError("scene", "a scene file is required");
    Scene scene = load_scene(scene_path);
    if (out_dir.empty())
        out_dir = scene.output.directory;
    if (vtu_every >= 0)
        scene.output.vtu_every = vtu_every;
    std::error_code ec;
    fs::create_directories(out_dir, ec);
    if (ec || !fs::is_directory(out_dir))
        throw InputError(out_dir, "cannot create output directory");

    Simulator sim(std::move(scene));
    const Scene& sc = sim.scene();
    if (stored) {
        if (!stored->scene.empty() && fs::weakly_canonical(stored->scene, ec) != fs::weakly_canonical(scene_path, ec))
            std::fprintf(stderr, "diffipc: warning: the trajectory was written for %s, not %s\n", stored->scene.c_str(),
                scene_path.c_str());
        sim.resume(stored->trajectory, stored->contact);
        if (!quiet)
            std::printf("diffipc: resuming %s at step %d\n", out_dir.c_str(), sim.steps_done());
    }
    if (!quiet)
        std::printf("diffipc: %s: %ld vertices, %ld elements, %d bodies, %s, dt = %g s, %d steps\n", scene_path.c_str(),
            long(sim.mesh().num_vertices()), long(sim.mesh().num_elements()), int(sc.bodies.size()),
            to_string(sc.time.integrator).c_str(), sc.time.dt, sc.time.steps);

    const std::string summary_path = (fs::path(out_dir) / "summary.json").string();
    const std::string pvd_path = (fs::path(out_dir) / "trajectory.pvd").string();
    std::unique_ptr<TrajectoryWriter> h5;
    const std::string h5_path = (fs::path(out_dir) / "trajectory.h5").string();
    if (sc.output.hdf5 || stored) {
        // A restart copies the stored steps into a new file, which then replaces the old one.
        const std::string path = stored ? h5_path + ".restart" : h5_path;
        h5 = std::make_unique<TrajectoryWriter>(path, sim.mesh(), stored ? stored->trajectory : sim.trajectory(),
            sim.contact() != nullptr,
            std::vector<std::pair<std::string, std::string>> {
                { "diffipc_version", DIFFIPC_VERSION }, { "scene", sc.source } });
        if (stored) {
            for (const StepRecord& r : stored->trajectory.steps)
                h5->append(r);
            h5->flush();
            if (std::rename(path.c_str(), h5_path.c_str()) != 0)
                throw InputError(h5_path, "cannot replace the trajectory with its continued copy");
        }
    }

    std::vector<std::pair<double, std::string>> vtu_files;
    if (stored)
        for (int k = 0; k <= sim.steps_done(); ++k) {
            const std::string name = "frame_" + std::to_string(k) + ".vtu";
            if (fs::exists(fs::path(out_dir) / name))
                vtu_files.emplace_back(
                    k == 0 ? stored->trajectory.initial_time : stored->trajectory.step(k).time, name);
        }
    stored.reset();
    auto write_frame = [&](int index, double t, const VectorXd& x, const VectorXd& v) {
        const std::string name = "frame_" + std::to_string(index) + ".vtu";
        write_vtu((fs::path(out_dir) / name).string(), sim, x, v);
        vtu_files.emplace_back(t, name);
    };
    if (sc.output.vtu_every > 0 && sim.steps_done() == 0)
        write_frame(0, 0.0, sim.positions(), sim.velocities());

    // Outputs are brought up to date output.flush_interval (1 s) apart: trajectory.h5 flushed,
    // summary.json (status RUNNING) and the .pvd replaced. A step's record is dropped once
    // written (its totals stay), so memory does not grow with the number of steps.
    double output_seconds = 0; // trajectory.h5, VTU frames, summary.json, .pvd
    auto bring_up_to_date = [&](const char* status) {
        const Timer timer;
        if (h5)
            h5->flush();
        if (!vtu_files.empty())
            write_pvd(pvd_path, vtu_files);
        nlohmann::json summary = summary_json(sim);
        if (status)
            summary["status"] = status;
        summary["wall_time"]["output"] = output_seconds;
        write_json(summary_path, summary);
        timer.add_to(output_seconds);
    };
    g_stop_signal = 0;
    std::signal(SIGINT, on_stop_signal);
    std::signal(SIGTERM, on_stop_signal);
    bring_up_to_date("RUNNING");

    Timer since_print, since_flush;
    const int total = sc.time.steps;
    while (sim.steps_done() < total && !g_stop_signal) {
        if (sim.step() != StepStatus::CONVERGED)
            break;
        const StepRecord& r = sim.trajectory().steps.back();
        {
            const Timer timer;
            if (h5)
                h5->append(r);
            if (sc.output.vtu_every > 0 && r.index % sc.output.vtu_every == 0)
                write_frame(r.index, r.time, r.positions, r.velocities);
            timer.add_to(output_seconds);
        }
        if (!quiet && (total <= 50 || since_print.seconds() > 1.0 || r.index == total)) {
            std::printf("  step %d/%d  t = %.4g s  newton %d  residual %.2e  %.3f s/step  min volume ratio %.3f\n",
                r.index, total, r.time, r.newton_iterations, r.residual, r.wall_time, r.min_volume_ratio);
            std::fflush(stdout);
            since_print = Timer();
        }
        sim.forget_records();
        if (since_flush.seconds() >= sc.output.flush_interval) {
            bring_up_to_date("RUNNING");
            since_flush = Timer();
        }
    }
    const int stop_signal = g_stop_signal;
    std::signal(SIGINT, SIG_DFL);
    std::signal(SIGTERM, SIG_DFL);

    const Trajectory& tr = sim.trajectory();
    const bool interrupted = stop_signal != 0 && tr.final_status == StepStatus::CONVERGED && sim.steps_done() < total;
    if (h5) {
        const Timer timer;
        h5->close();
        timer.add_to(output_seconds);
    }
    bring_up_to_date(interrupted ? "INTERRUPTED" : nullptr);

    if (interrupted) {
        std::fprintf(stderr, "diffipc: interrupted by %s after %d of %d steps; wrote %s\n",
            stop_signal == SIGINT ? "SIGINT" : "SIGTERM", sim.steps_done(), total, out_dir.c_str());
        return interrupted_exit_code(stop_signal);
    }
    if (tr.final_status != StepStatus::CONVERGED) {
        std::fprintf(stderr, "diffipc: %s\n", tr.failure_message.c_str());
        return 2;
    }
    if (!quiet)
        std::printf("diffipc: %d steps converged in %.2f s (%d Newton iterations); wrote %s (output %.3f s, %.1f%% "
                    "of the steps' time)\n",
            tr.committed(), tr.wall_time, tr.newton_iterations, out_dir.c_str(), output_seconds,
            tr.wall_time > 0 ? 100 * output_seconds / tr.wall_time : 0.0);
    return 0;
}

int validate(const std::string& scene_path)
{
    const Scene scene = load_scene(scene_path);
    std::printf("%s: valid %dD scene, %zu bodies, %ld vertices, %ld elements, %s, %d steps of %g s\n",
        scene_path.c_str(), scene.dim, scene.bodies.size(), long(scene.mesh.num_vertices()),
        long(scene.mesh.num_elements()), to_string(scene.time.integrator).c_str(), scene.time.steps, scene.time.dt);
    return 0;
}

std::string version_text()
{
    try {
        ensure_threads_configured();
    } catch (const InputError& e) {
        return std::string("diffipc " DIFFIPC_VERSION "\ndiffipc: error: ") + e.what() + "\n";
    }
    return "diffipc " DIFFIPC_VERSION "\n" + describe(thread_config());
}

} // namespace

int main(int argc, char** argv)
{
    // Before anything else: libgomp must see OMP_WAIT_POLICY when it is loaded (threads.hpp).
    prepare_process_environment(argv);

    CLI::App app { "diffipc: differentiable IPC elastodynamics" };
    app.require_subcommand(1);
    app.fallthrough();
    app.set_version_flag("--version", version_text, "Print the version and the thread configuration");
    int threads = -1;
    app.add_option("--threads", threads,
           "threads for TBB, OpenBLAS and OpenMP (default: DIFFIPC_THREADS, else the file's \"threads\", else the "
           "cores this process may use)")
        ->check(CLI::Range(1, 4096));
    auto* info_cmd = app.add_subcommand("info", "Print the version and the effective thread configuration");

    std::string scene_path, out_dir, restart_dir;
    int vtu_every = -1;
    bool quiet = false;
    auto* sim_cmd
        = app.add_subcommand("simulate", "Run a scene; writes trajectory.h5, summary.json and optional VTU files");
    sim_cmd->add_option("scene", scene_path, "scene file (JSON); with --restart, default: the one the run was for");
    sim_cmd->add_option("--restart", restart_dir,
        "continue the run in this output directory from the last committed step of its trajectory.h5");
    sim_cmd->add_option("-o,--output", out_dir, "output directory (default: the scene's output.directory)");
    sim_cmd->add_option("--vtu-every", vtu_every, "write a VTU frame every N steps (0: none; default: the scene's)")
        ->check(CLI::Range(0, 1 << 30));
    sim_cmd->add_flag("-q,--quiet", quiet, "no progress output");

    std::string validate_path;
    auto* val_cmd = app.add_subcommand("validate", "Check a scene file and report what it contains");
    val_cmd->add_option("scene", validate_path, "scene file (JSON)")->required();

    BenchOptions bench_options;
    auto* bench_cmd = app.add_subcommand("bench", "Run the fixed benchmark scenes and print per-phase timings");
    bench_cmd->add_option("--size", bench_options.size, "small | full")->check(CLI::IsMember({ "small", "full" }));
    bench_cmd->add_option("--steps", bench_options.steps, "time steps per scene (the first is a warm-up)");
    bench_cmd->add_option("--suite", bench_options.suite, "forward | contact | scenes | adjoint | scaling")
        ->check(CLI::IsMember({ "forward", "contact", "scenes", "adjoint", "scaling" }));
    bench_cmd
        ->add_option("--thread-counts", bench_options.thread_counts,
            "scaling suite: thread counts, comma-separated (default 1, 2, 4, ... the usable cores)")
        ->delimiter(',')
        ->check(CLI::Range(1, 4096));
    bench_cmd->add_option(
        "--scenes", bench_options.scenes, "scaling suite: any of 50k,200k,contact,adjoint,factor (default: all)");
    bench_cmd->add_option("--source-dir", bench_options.source_dir, "repository root, where studies/ lives");
    bench_cmd->add_option("--friction", bench_options.friction, "contact suite: friction coefficient (0: none)")
        ->check(CLI::Range(0.0, 10.0));

    std::string problem_path;
    int directions = 0;
    auto* grad_cmd = app.add_subcommand(
        "gradcheck", "Adjoint gradient of a problem file against finite differences (Taylor table)");
    grad_cmd->add_option("problem", problem_path, "problem file (JSON)")->required();
    grad_cmd->add_option("--directions", directions, "random directions (default: the file's, else 2)")
        ->check(CLI::Range(1, 1 << 20));

    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForAllHelp& e) {
        return app.exit(e);
    } catch (const CLI::CallForVersion& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        // A usage error is bad input like any other: exit 1, one line (and where to look).
        std::fprintf(stderr, "diffipc: error: %s (see diffipc --help)\n", e.what());
        return 1;
    }

    try {
        ensure_threads_configured();
        if (threads > 0)
            set_threads(threads, ThreadSource::EXPLICIT, "--threads");
        if (*info_cmd) {
            std::printf("%s", version_text().c_str());
            return 0;
        }
        if (*sim_cmd)
            return simulate(scene_path, out_dir, vtu_every, quiet, restart_dir);
        if (*val_cmd)
            return validate(validate_path);
        if (*bench_cmd)
            return run_bench(bench_options);
        if (*grad_cmd)
            return gradcheck(problem_path, directions);
    } catch (const InputError& e) {
        std::fprintf(stderr, "diffipc: error: %s\n", e.what());
        return 1;
    } catch (const AdjointError& e) {
        std::fprintf(stderr, "diffipc: %s\n", e.what());
        return 2;
        std::fprintf(stderr, "diffipc: error: %s\n", e.what());
        return 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "diffipc: internal error: %s\n", e.what());
        return 3;
    }
    return 0;
}
