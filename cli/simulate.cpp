// `diffipc simulate`: a scene run with streamed output, stopped cleanly by SIGINT/SIGTERM,
// and continued with --restart (docs/output_format.md).

#include "cli/simulate.hpp"

#include "cli/stop_signal.hpp"

#include "forward/common/error.hpp"
#include "forward/common/timer.hpp"
#include "forward/io/output.hpp"
#include "forward/io/trajectory_reader.hpp"
#include "forward/io/vtu_frame.hpp"
#include "forward/scene/scene.hpp"
#include "forward/simulation/simulator.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>

namespace fs = std::filesystem;

namespace diffipc {

namespace {

    /// States read for a resumed run: the integrators' history (BDF2 needs two).
    constexpr int RESUME_STATES = 2;
    /// Steps whose states are read at once while a restart copies the stored trajectory.
    constexpr int COPY_BLOCK = 256;

    /// Appends every stored step to `h5`, reading the states in blocks and dropping each
    /// block once written, so that memory does not grow with the stored run's length.
    void copy_steps(StoredTrajectory& stored, TrajectoryWriter& h5)
    {
        Trajectory& tr = stored.trajectory;
        const int total = tr.committed(), kept_from = std::max(1, total - RESUME_STATES + 1);
        for (int first = 1; first <= total; first += COPY_BLOCK) {
            const int last = std::min(total, first + COPY_BLOCK - 1);
            if (first < kept_from)
                read_states(stored, first, std::min(last, kept_from - 1));
            for (int k = first; k <= last; ++k) {
                h5.append(tr.step(k));
                if (k < kept_from)
                    tr.step(k).release_state();
            }
        }
    }

} // namespace

std::unique_ptr<Simulator> open_simulator(Scene scene, const std::string& scene_path)
{
    try {
        return std::make_unique<Simulator>(std::move(scene));
    } catch (const InputError& e) {
        throw InputError(scene_path, e.what());
    }
}

int simulate(SimulateOptions options)
{
    std::string& scene_path = options.scene_path;
    std::string& out_dir = options.out_dir;
    const std::string& restart = options.restart;
    const bool quiet = options.quiet;
    // --restart DIR: the run in DIR goes on from its last committed step in trajectory.h5.
    std::unique_ptr<StoredTrajectory> stored;
    if (!restart.empty()) {
        if (!out_dir.empty() && fs::path(out_dir) != fs::path(restart))
            throw InputError("--restart", "continues the run in its own directory; leave -o out");
        out_dir = restart;
        // The last two states (the integrators' history); the others are copied in blocks below.
        stored = std::make_unique<StoredTrajectory>(
            read_trajectory((fs::path(restart) / "trajectory.h5").string(), RESUME_STATES));
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
    if (options.vtu_every >= 0)
        scene.output.vtu_every = options.vtu_every;
    if (options.steps >= 0)
        scene.time.steps = options.steps;
    if (!options.device.empty())
        select_device(scene, options.device, "--device");
    std::error_code ec;
    fs::create_directories(out_dir, ec);
    if (ec || !fs::is_directory(out_dir))
        throw InputError(out_dir, "cannot create output directory");

    const std::unique_ptr<Simulator> simulator = open_simulator(std::move(scene), scene_path);
    Simulator& sim = *simulator;
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
                { "diffipc_version", DIFFIPC_VERSION }, { "scene", sc.source } },
            sc.time.adaptive.enabled);
        if (stored) {
            try {
                copy_steps(*stored, *h5);
                h5->flush();
            } catch (...) {
                h5.reset();
                std::remove(path.c_str());
                throw;
            }
            if (std::rename(path.c_str(), h5_path.c_str()) != 0)
                throw InputError(h5_path, "cannot replace the trajectory with its continued copy");
        }
    }

    // The .pvd lists every frame's bodies (part 0) and obstacles (part 1); a restart keeps
    // the frames already written up to its step.
    std::vector<PvdEntry> vtu_files;
    if (stored)
        for (int k = 0; k <= sim.steps_done(); ++k) {
            const double t = k == 0 ? stored->trajectory.initial_time : stored->trajectory.step(k).time;
            const std::string parts[2] = { body_frame_name(k), obstacle_frame_name(k) };
            for (int part = 0; part < 2; ++part)
                if (std::error_code ec; fs::exists(fs::path(out_dir) / parts[part], ec))
                    vtu_files.push_back({ t, part, parts[part] });
        }
    stored.reset();
    // A frame shows the simulator's committed state (the contact and friction forces are those at it).
    auto write_frame = [&](int index, double t) {
        for (PvdEntry& e : write_vtu_frame(out_dir, index, t, sim, sc.output.vtu_encoding))
            vtu_files.push_back(std::move(e));
    };
    // A write that fails (a full disk, a file linked to /dev/full) ends the run, exit 1 naming the
    // file: trajectory.h5 is closed with every committed step, and summary.json, where it can still
    // be written, says OUTPUT_FAILED and why. Before, a run that lost its output could exit 0.
    const auto output = [&](const std::function<void()>& write) {
        try {
            write();
        } catch (const InputError& e) {
            try {
                if (h5)
                    h5->close();
            } catch (const InputError&) {
            }
            nlohmann::json summary = summary_json(sim);
            summary["status"] = "OUTPUT_FAILED";
            summary["failure"] = e.what();
            try {
                write_json(summary_path, summary);
            } catch (const InputError&) {
            }
            throw;
        }
    };
    // An initial state that cannot start a step (an inverted element, intersecting bodies) has
    // no finite stresses to show: no frame 0; step 1 fails with INVALID_INITIAL_STATE and why.
    if (sc.output.vtu_every > 0 && sim.steps_done() == 0 && sim.state_problem().empty())
        output([&] { write_frame(0, 0.0); });

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
    // A stop signal ends the run after the current step (a second one at once: the
    // trajectory keeps every step up to its last flush).
    catch_stop_signals();
    output([&] { bring_up_to_date("RUNNING"); });

    Timer since_print, since_flush;
    const int total = sc.time.steps;
    while (sim.steps_done() < total && !stop_signal()) {
        if (sim.step() != StepStatus::CONVERGED)
            break;
        const StepRecord& r = sim.trajectory().steps.back();
        {
            const Timer timer;
            output([&] {
                if (h5)
                    h5->append(r);
                if (sc.output.vtu_every > 0 && r.index % sc.output.vtu_every == 0)
                    write_frame(r.index, r.time);
            });
            timer.add_to(output_seconds);
        }
        if (!quiet && (total <= 50 || since_print.seconds() > 1.0 || r.index == total)) {
            std::printf("  step %d/%d  t = %.4g s  newton %d  residual %.2e  %.3f s/step  min volume ratio %.3f",
                r.index, total, r.time, r.newton_iterations, r.residual, r.wall_time, r.min_volume_ratio);
            if (r.substeps > 0)
                std::printf("  %d sub-steps (%d cuts, smallest %.3g s)", r.substeps, r.cuts, r.min_increment);
            if (r.control_steps > 0)
                std::printf("  %d displacement-controlled", r.control_steps);
            if (r.relaxation_steps > 0)
                std::printf("  %d relaxation", r.relaxation_steps);
            std::printf("\n");
            std::fflush(stdout);
            since_print = Timer();
        }
        sim.forget_records();
        if (since_flush.seconds() >= sc.output.flush_interval) {
            output([&] { bring_up_to_date("RUNNING"); });
            since_flush = Timer();
        }
    }
    const int stopped_by = release_stop_signals();

    const Trajectory& tr = sim.trajectory();
    const bool interrupted = stopped_by != 0 && tr.final_status == StepStatus::CONVERGED && sim.steps_done() < total;
    output([&] {
        if (h5) {
            const Timer timer;
            h5->close();
            timer.add_to(output_seconds);
        }
        bring_up_to_date(interrupted ? "INTERRUPTED" : nullptr);
    });

    if (interrupted) {
        std::fprintf(stderr, "diffipc: interrupted by %s after %d of %d steps; wrote %s\n",
            stopped_by == SIGINT ? "SIGINT" : "SIGTERM", sim.steps_done(), total, out_dir.c_str());
        return interrupted_exit_code(stopped_by);
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

} // namespace diffipc
