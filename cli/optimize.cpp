// diffipc optimize: a problem file's optimization run with its outputs, and its resume (docs/optimization.md).

#include "cli/optimize.hpp"

#include "cli/distributed_run.hpp"
#include "cli/stop_signal.hpp"

#include "forward/common/error.hpp"
#include "forward/common/timer.hpp"
#include "forward/io/output.hpp"
#include "forward/io/replace_file.hpp"
#include "forward/io/vtu_writer.hpp"
#include "forward/scene/json_input.hpp"
#include "shape_opt/design_problem.hpp"
#include "shape_opt/optimization_history.hpp"
#include "shape_opt/optimizer/optimizer_json.hpp"
#include "shape_opt/optimizer/taylor_check.hpp"
#include "shape_opt/reduced_functional.hpp"
#include "shape_opt/remesh.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>

namespace fs = std::filesystem;

namespace diffipc {

namespace {

    /// The last iterate counts as the best point seen when its f is above the best one's by at
    /// most this, relatively (round-off and the forward solves' tolerances).
    constexpr double BEST_POINT_TOLERANCE = 1e-8;

    /// The rest design: the bodies' rest mesh at p, with the per-element material as cell data.
    void write_design_vtu(const std::string& path, const ReducedFunctional& rf, const VectorXd& p)
    {
        const SimulationParameters sp = rf.simulation_parameters_of(p);
        const Scene& scene = rf.scene();
        const Mesh& mesh = scene.mesh;
        const int d = scene.dim;
        VtuGrid grid;
        for (Index v = 0; v < scene.body_vertices; ++v)
            grid.add_point(sp.rest_positions.data() + v * d, d);
        for (Index e = 0; e < mesh.num_elements(); ++e) {
            Index cell[4];
            for (int a = 0; a <= d; ++a)
                cell[a] = mesh.elements(e, a);
            grid.add_cell(d == 2 ? VtkCell::TRIANGLE : VtkCell::TETRA, cell, d + 1);
        }
        const auto cell_array = [&](const char* name, const VectorXd& values) {
            if (values.size() == mesh.num_elements())
                grid.cell_data.push_back(
                    { name, 1, std::vector<double>(values.data(), values.data() + values.size()) });
        };
        cell_array("E", sp.youngs_modulus);
        cell_array("nu", sp.poisson_ratio);
        cell_array("mu", sp.mu);
        cell_array("lambda", sp.lambda);
        cell_array("density", sp.density);
        std::vector<std::int32_t> body(size_t(mesh.num_elements()));
        for (Index e = 0; e < mesh.num_elements(); ++e)
            body[size_t(e)] = mesh.element_body[e];
        grid.cell_data.push_back({ "body", 1, body });
        // ASCII (every double exact): meshio 1.x misreads some raw appended files (it rewrites
        // offsets in place and can match a rewritten one; docs/output_format.md), and a rest
        // design is small.
        write_vtu(path, grid, VtuEncoding::ASCII);
    }

    /// The problem with x as every parameter entry's "initial", its scenes inlined and their
    /// paths absolute (shape_opt/remesh.hpp), so that it loads from the output directory.
    nlohmann::json optimal_problem(const ReducedFunctional& rf, const VectorXd& x)
    {
        nlohmann::json doc = self_contained_document(rf);
        Index at = 0;
        const auto layout = rf.design_layout();
        for (size_t k = 0; k < layout.size(); ++k) {
            const Index n = layout[k].second;
            doc["parameters"][k]["initial"] = std::vector<double>(x.data() + at, x.data() + at + n);
            at += n;
        }
        return doc;
    }

    /// Stop reasons after which a run is over: a resume has nothing to do.
    bool converged(const std::string& reason)
    {
        return reason == "gradient_tolerance" || reason == "x_tolerance" || reason == "f_tolerance"
            || reason == "objective_target";
    }

    /// Stop reasons from which a resume would start in the state that ended the run.
    bool ended_by_optimizer(const std::string& reason)
    {
        return reason == "line_search_stalled" || reason == "infeasible" || reason == "invalid_start"
            || reason == "failed";
    }

    std::string join(const std::vector<std::string>& names)
    {
        std::string text = "[";
        for (size_t i = 0; i < names.size(); ++i)
            text += (i ? ", \"" : "\"") + names[i] + "\"";
        return text + "]";
    }

    /// What a resumed run takes over from the run in its directory.
    struct Resume {
        std::string directory;
        StoredHistory history; ///< rows up to the state's iteration only
        RunState state;
        std::string summary_reason; ///< the last summary.json's stop_reason ("" without one)
    };

    /// @brief Reads the run in `directory`, checks that it can go on, and finds its problem.
    /// @return false (after a message) when the run already converged: nothing to do
    /// @throws InputError naming the file or field when it cannot be resumed
    bool read_resume(Resume& r, std::string& problem_path)
    {
        const fs::path dir = r.directory;
        std::error_code ec;
        if (!fs::is_directory(dir, ec))
            throw InputError(
                r.directory, "no such directory (--resume takes the output directory of a run of diffipc optimize)");
        const std::string history_path = (dir / "history.h5").string();
        if (!fs::exists(history_path, ec))
            throw InputError(history_path,
                "missing: " + r.directory
                    + " holds no optimization history to resume (not an output directory of "
                      "diffipc optimize, or a run that was stopped before it started)");
        const std::string summary_path = (dir / "summary.json").string();
        if (fs::exists(summary_path, ec)) {
            nlohmann::json summary;
            try {
                std::ifstream in(summary_path);
                summary = nlohmann::json::parse(in);
            } catch (const nlohmann::json::exception& e) {
                throw InputError(summary_path, std::string("cannot be read: ") + e.what());
            }
            if (summary.contains("stop_reason") && summary["stop_reason"].is_string())
                r.summary_reason = summary["stop_reason"].get<std::string>();
            const std::string message = summary.value("message", std::string());
            const int iterations = summary.value("iterations", -1);
            if (converged(r.summary_reason)) {
                std::printf("diffipc: the run in %s converged (stop_reason %s after %d iterations: %s); nothing to "
                            "resume\n",
                    r.directory.c_str(), r.summary_reason.c_str(), iterations, message.c_str());
                return false;
            }
            if (ended_by_optimizer(r.summary_reason))
                throw InputError(summary_path,
                    "the run ended with stop_reason " + r.summary_reason + " (" + message
                        + "): a resume would start from the state that ended it; start a new run from "
                        + (dir / "optimal_problem.json").string() + " instead");
        }
        r.history = read_history(history_path);
        const std::string state_path = (dir / "optimizer_state.h5").string();
        if (!fs::exists(state_path, ec))
            throw InputError(state_path, "missing: the run completed no iteration to continue from");
        r.state = read_run_state(state_path);
        const int k = r.state.checkpoint.iteration;
        auto& rows = r.history.rows;
        if (k < 0 || k >= int(rows.size()))
            throw InputError(history_path,
                "holds iterations 0 to " + std::to_string(int(rows.size()) - 1)
                    + ", but optimizer_state.h5 is at iteration " + std::to_string(k)
                    + ": the files do not belong together");
        if (r.state.checkpoint.x.size() != r.history.header.design_size || rows[size_t(k)].x != r.state.checkpoint.x)
            throw InputError(state_path,
                "its x differs from history.h5's at iteration " + std::to_string(k)
                    + ": the files do not belong together");
        rows.resize(size_t(k) + 1); // rows after the state's iteration are done again
        if (!problem_path.empty() && fs::exists(dir / "current_problem.json", ec))
            throw InputError(problem_path,
                "the run in " + r.directory
                    + " remeshed: resume it without a problem file (it goes on with current_problem.json, the "
                      "problem on its newest mesh)");
        if (problem_path.empty()) {
            // The problem on the newest mesh when the run remeshed, else as it started.
            problem_path = (dir
                / (fs::exists(dir / "current_problem.json", ec) ? "current_problem.json" : "initial_problem.json"))
                               .string();
            if (!fs::exists(problem_path, ec))
                throw InputError(problem_path, "missing: give the problem file of the run");
        }
        return true;
    }

    /// @brief The final Taylor check's direction scale per design variable: diffipc gradcheck's
    /// (ReducedFunctional::scales()) where x is p; through maps, one factor on all variables
    /// that puts the maps' response to a unit change of every variable at those scales.
    VectorXd design_scales(const ReducedFunctional& rf, const VectorXd& x)
    {
        const VectorXd p = rf.parameters_of(x);
        if (x.size() == rf.size() && p == x)
            return rf.scales();
        const double eta = 1e-6;
        const VectorXd dp = (rf.parameters_of(x + VectorXd::Constant(x.size(), eta)) - p) / eta;
        const double largest = (dp.array().abs() / rf.scales().array()).maxCoeff();
        return VectorXd::Constant(x.size(), std::isfinite(largest) && largest > 0 ? 1 / largest : 1.0);
    }

    /// The final Taylor check into summary.json and, unless quiet, onto stdout.
    void record_taylor_check(const TaylorCheck& check, const TaylorCheckSettings& settings, double scale,
        nlohmann::json& summary, bool quiet)
    {
        nlohmann::json rows = nlohmann::json::array();
        const auto number = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
        for (size_t k = 0; k < check.steps.size(); ++k)
            rows.push_back({ { "step", check.steps[k] }, { "J_change", number(check.changes[k] * scale) },
                { "remainder", number(check.remainders[k] * scale) },
                { "rate", k == 0 ? nlohmann::json(nullptr) : number(check.rates[k - 1]) },
                { "settle_rate", k < 2 ? nlohmann::json(nullptr) : number(check.settle_rates[k - 2]) } });
        summary["final_taylor_check"] = { { "verdict", check.verdict }, { "reason", check.reason },
            { "slope", check.slope * scale }, { "floor", check.floor * scale }, { "seed", settings.seed },
            { "evaluations", check.evaluations }, { "rejected", check.rejected }, { "rows", rows } };
        if (quiet)
            return;
        const auto rate_text = [](double r) {
            char text[16] = "-";
            if (std::isfinite(r))
                std::snprintf(text, sizeof text, "%.2f", r);
            return std::string(text);
        };
        std::string rates;
        for (double r : check.rates)
            rates += " " + rate_text(r);
        std::printf(
            "final Taylor check at the last iterate: %s (remainder rates%s; %d evaluations, not counted above)\n",
            check.verdict.c_str(), rates.c_str(), check.evaluations);
        // The table where the verdict needs reading, as diffipc gradcheck prints it, with the
        // signed remainder over h^2 (it settles where J is smooth) and the rate the verdict reads.
        if (check.verdict != "smooth") {
            std::printf("  %-10s %-14s %-6s %-14s %-6s %-14s %-6s\n", "h", "|J(h)-J(0)|", "rate", "|J(h)-J(0)-h g.d|",
                "rate", "R/h^2", "rate");
            for (size_t k = 0; k < check.steps.size(); ++k) {
                const double h = check.steps[k], R = check.remainders[k] * scale;
                std::printf("  %-10.3e %-14.6e %-6s %-14.6e %-6s %-14.6e %-6s\n", h, check.changes[k] * scale,
                    k == 0 ? "" : rate_text(std::log2(check.changes[k - 1] / check.changes[k])).c_str(), std::abs(R),
                    k == 0 ? "" : rate_text(check.rates[k - 1]).c_str(), R / (h * h),
                    k < 2 ? "" : rate_text(check.settle_rates[k - 2]).c_str());
            }
            std::printf("  %s\n", check.reason.c_str());
        }
        std::fflush(stdout);
    }

} // namespace

int optimize(const OptimizeOptions& options)
{
    const Timer wall;
    std::string problem_path = options.problem_path, out_dir = options.out_dir;
    std::unique_ptr<Resume> resume;
    if (!options.resume_dir.empty()) {
        if (!out_dir.empty() && fs::path(out_dir).lexically_normal() != fs::path(options.resume_dir).lexically_normal())
            throw InputError("--resume", "continues the run in its own directory; leave -o out");
        resume = std::make_unique<Resume>();
        resume->directory = out_dir = options.resume_dir;
        if (!read_resume(*resume, problem_path))
            return 0;
    }
    if (problem_path.empty())
        throw InputError("problem", "a problem file is required (or --resume DIR)");

    ReducedFunctional rf = ReducedFunctional::load(problem_path, options.device);
    rf.set_distribution(options.distribution);
    OptimizerSettings settings = parse_optimizer_settings(JsonField(rf.optimizer_spec(), "optimizer"));
    settings.lower = rf.design_lower();
    settings.upper = rf.design_upper();
    if (options.max_iterations >= 0)
        settings.max_iterations = options.max_iterations;
    if (options.max_seconds >= 0)
        settings.max_seconds = options.max_seconds;
    int design_every = 1;
    {
        const nlohmann::json& doc = rf.document();
        if (doc.contains("output")) {
            const JsonField out(doc["output"], "output");
            out.require_object({ "directory", "design_every" });
            if (out.has("design_every"))
                design_every = out["design_every"].integer(0);
            if (out_dir.empty() && out.has("directory"))
                out_dir = (fs::path(rf.base_directory()) / out["directory"].string()).string();
        }
    }
    if (out_dir.empty())
        out_dir = (fs::path("output") / fs::path(problem_path).stem()).string();

    const auto& constraints = rf.constraints();
    HistoryHeader header;
    header.problem = fs::absolute(problem_path).lexically_normal().string();
    header.algorithm = to_string(settings.algorithm);
    header.design_size = rf.design_size();
    for (const ConstraintSpec& c : constraints)
        header.constraint_names.push_back(c.name);

    const fs::path dir = out_dir;
    const std::string state_path = (dir / "optimizer_state.h5").string();
    std::error_code ec;
    if (resume) {
        // The problem must be the run's: the same design variables and constraints (its
        // settings may differ: a larger budget, other tolerances).
        const HistoryHeader& stored = resume->history.header;
        if (header.design_size != stored.design_size)
            throw InputError(problem_path,
                "has " + std::to_string(header.design_size) + " design variables, the run in " + out_dir + " "
                    + std::to_string(stored.design_size) + ": not the problem of that run");
        if (header.constraint_names != stored.constraint_names)
            throw InputError(problem_path,
                "has the constraints " + join(header.constraint_names) + ", the run in " + out_dir + " "
                    + join(stored.constraint_names) + ": not the problem of that run");
        if (settings.algorithm != resume->state.checkpoint.algorithm)
            throw InputError("optimizer.algorithm",
                "\"" + header.algorithm + "\" cannot continue the run in " + out_dir + " of \""
                    + to_string(resume->state.checkpoint.algorithm)
                    + "\" (start a new run from its optimal_problem.json instead)");
        const OptimizerCheckpoint& c = resume->state.checkpoint;
        if (settings.max_iterations > 0 && c.iteration >= settings.max_iterations)
            throw InputError("optimizer.max_iterations",
                "the run in " + out_dir + " has done " + std::to_string(c.iteration) + " iterations of its budget of "
                    + std::to_string(settings.max_iterations)
                    + ": raise it (--max-iterations N, or optimizer.max_iterations in " + problem_path + ") to go on");
        if (settings.max_seconds > 0 && c.elapsed_seconds >= settings.max_seconds)
            throw InputError("optimizer.max_seconds",
                "the run in " + out_dir + " has run " + format_number(c.elapsed_seconds) + " s of its budget of "
                    + format_number(settings.max_seconds)
                    + " s: raise it (--max-seconds S, or optimizer.max_seconds in " + problem_path + ") to go on");
        header.problem = stored.problem; // the run's, not the file it is resumed with
    }
    // Settings that do not fit the problem (constraints given to L-BFGS-B, bad bounds, an option
    // the library refuses) are refused before anything is written or printed.
    DesignProblem design_problem(rf);
    check_optimizer_settings(design_problem, resume ? resume->state.checkpoint.x : rf.design_initial(), settings);
    if (!resume) {
        fs::create_directories(dir, ec);
        if (ec || !fs::is_directory(dir))
            throw InputError(out_dir, "cannot create output directory");
        // What an earlier run in the directory left would describe another run.
        for (const char* stale :
            { "summary.json", "optimizer_state.h5", "current_problem.json", "remeshes.json", "best_problem.json" })
            fs::remove(dir / stale, ec);
        for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
            const std::string name = it->path().filename().string();
            if (name.rfind("remesh_", 0) == 0 && it->path().extension() == ".msh")
                fs::remove(it->path(), ec);
        }
        // The problem as started, for a resume: written unless it is the file being run.
        const fs::path copy = dir / "initial_problem.json";
        if (!(fs::exists(copy, ec) && fs::equivalent(copy, problem_path, ec)))
            write_json(copy.string(), self_contained_document(rf));
    }

    design_problem.set_remesh_directory(out_dir);
    if (resume)
        design_problem.set_objective_scale(resume->state.objective_scale);
    // The remeshes so far (DIR/remeshes.json), kept for a resume: their records, the attempts
    // (counted against remesh.max), the trigger and the failed attempts' time.
    const std::string remeshes_path = (dir / "remeshes.json").string();
    if (resume && fs::exists(remeshes_path, ec)) {
        const nlohmann::json saved = parse_json_text(read_input_file(remeshes_path, "remesh state"), remeshes_path);
        std::vector<RemeshRecord> records;
        try {
            for (size_t i = 0; i < saved.at("records").size(); ++i)
                records.push_back(remesh_record_from_json(saved["records"][i], remeshes_path));
            design_problem.restore_remeshes(records, saved.at("attempts").get<int>(), saved.at("trigger").get<double>(),
                saved.at("failed_seconds").get<double>());
        } catch (const nlohmann::json::exception&) {
            throw InputError(remeshes_path, "is not the remesh state diffipc optimize writes");
        }
    }
    const auto remesh_records = [&]() {
        nlohmann::json list = nlohmann::json::array();
        for (const RemeshRecord& r : design_problem.remeshes())
            list.push_back(remesh_record_json(r));
        return list;
    };
    design_problem.on_remesh_attempt = [&]() {
        if (!options.quiet && !design_problem.remesh_failure().empty()) {
            std::printf("  remesh refused: %s\n", design_problem.remesh_failure().c_str());
            std::fflush(stdout);
        }
        write_json(remeshes_path,
            { { "attempts", design_problem.remesh_attempts() }, { "trigger", design_problem.remesh_trigger() },
                { "failed_seconds", design_problem.failed_remesh_seconds() }, { "records", remesh_records() } });
    };
    const auto objective_scale = [&]() { return design_problem.objective_scale(); };
    const auto last_rejection = [&]() {
        return design_problem.last_rejection().empty() && resume ? resume->state.last_rejection
                                                                 : design_problem.last_rejection();
    };

    // A resumed run's outputs start with what the stopped run did up to the state's iteration.
    const double wall_before = resume ? resume->history.rows.back().wall_seconds : 0.0;
    HistoryWriter history(out_dir, header, resume ? resume->history.rows : std::vector<HistoryRow>());
    std::vector<PvdEntry> designs;
    double initial_value = std::nan("");
    if (resume) {
        initial_value = resume->history.rows.front().J;
        for (const HistoryRow& row : resume->history.rows) {
            const std::string name = "design_" + std::to_string(row.iteration) + ".vtu";
            if (fs::exists(dir / name, ec))
                designs.push_back({ double(row.iteration), 0, name });
        }
        if (!designs.empty())
            write_pvd((dir / "designs.pvd").string(), designs);
    }

    if (!options.quiet) {
        if (resume)
            std::printf("diffipc: resuming %s at iteration %d (J = %.6e)\n", out_dir.c_str(),
                resume->state.checkpoint.iteration, resume->history.rows.back().J);
        std::printf("diffipc: %s: %ld design variables, %zu constraints, %s\n", problem_path.c_str(),
            long(rf.design_size()), constraints.size(), to_string(settings.algorithm).c_str());
        std::printf("  %4s  %-13s", "iter", "J");
        for (const ConstraintSpec& c : constraints)
            std::printf("  %-12.12s", c.name.c_str());
        std::printf("  %-9s  %-9s  %4s  %8s  %8s\n", "|grad|", "step", "rej", "eval s", "opt s");
    }
    design_problem.on_iteration = [&](const IterationInfo& info) {
        HistoryRow row;
        row.iteration = info.iteration;
        row.x = *info.x;
        row.J = info.values->f * objective_scale();
        if (info.iteration == 0)
            initial_value = row.J;
        const VectorXd& g = design_problem.last_constraint_values();
        row.constraints.resize(Index(constraints.size()));
        for (size_t i = 0; i < constraints.size(); ++i)
            row.constraints[Index(i)] = Index(i) < g.size() ? g[Index(i)] : std::nan("");
        row.gradient_norm = info.gradient_norm;
        row.step_norm = info.step_norm;
        row.evaluations = info.evaluations;
        row.rejected = info.rejected;
        row.evaluation_seconds = info.evaluation_seconds;
        row.optimizer_seconds = info.optimizer_seconds;
        row.wall_seconds = wall_before + wall.seconds();
        // The row first, then the state: a run killed in between resumes from the iteration before.
        history.append(row);
        if (info.checkpoint)
            write_run_state(state_path, { *info.checkpoint, objective_scale(), last_rejection() });
        if (!options.quiet) {
            std::printf("  %4d  %-13.6e", info.iteration, row.J);
            for (Index i = 0; i < row.constraints.size(); ++i)
                std::printf("  %-12.5e", row.constraints[i]);
            std::printf("  %-9.2e  %-9.2e  %4d  %8.2f  %8.3f\n", info.gradient_norm, info.step_norm, info.rejected,
                info.evaluation_seconds, info.optimizer_seconds);
            std::fflush(stdout);
        }
        if (design_every > 0 && info.iteration % design_every == 0) {
            const std::string name = "design_" + std::to_string(info.iteration) + ".vtu";
            const ReducedFunctional& now = design_problem.functional();
            write_design_vtu((dir / name).string(), now, now.parameters_of(*info.x));
            designs.push_back({ double(info.iteration), 0, name });
            write_pvd((dir / "designs.pvd").string(), designs);
        }
        return stop_signal() == 0;
    };
    // After a remesh the run goes on from the values on the new mesh: they are its state now.
    design_problem.on_restart = [&](const OptimizerCheckpoint& c) {
        write_run_state(state_path, { c, objective_scale(), last_rejection() });
    };
    design_problem.on_remesh = [&](const RemeshRecord& r) {
        // The problem on the new mesh, for a resume (read_resume prefers it).
        write_json((dir / "current_problem.json").string(), self_contained_document(design_problem.functional()));
        if (!options.quiet) {
            std::printf("  remeshed after iteration %d: quality %.3f -> %.3f, %ld -> %ld elements, J %.6e -> %.6e "
                        "(%.2f s)\n",
                r.iteration, r.quality_before, r.quality_after, long(r.elements_before), long(r.elements_after),
                r.J_before, r.J_after, r.seconds);
            std::fflush(stdout);
        }
    };

    catch_stop_signals(); // the run stops after the current iteration
    const OptimizerResult result
        = minimize_design(design_problem, rf.design_initial(), settings, resume ? &resume->state.checkpoint : nullptr);
    int stopped_by = release_stop_signals();
    history.close();
    const std::string rejection = last_rejection(); // before the final check's evaluations

    nlohmann::json summary;
    summary["problem"] = header.problem;
    summary["algorithm"] = to_string(settings.algorithm);
    summary["stop_reason"] = to_string(result.reason);
    summary["message"] = result.message;
    summary["iterations"] = result.iterations;
    summary["evaluations"] = result.evaluations;
    summary["rejected"] = result.rejected;
    summary["last_rejection"] = rejection.empty() ? nlohmann::json(nullptr) : nlohmann::json(rejection);
    if (resume)
        summary["resumed_at_iteration"] = resume->state.checkpoint.iteration;
    if (std::isfinite(initial_value))
        summary["initial_J"] = initial_value;
    const double scale = objective_scale();
    std::vector<std::string> warnings;
    const auto warn = [&](const std::string& text) {
        warnings.push_back(text);
        std::fprintf(stderr, "diffipc: warning: %s\n", text.c_str());
    };
    const ReducedFunctional& now = design_problem.functional();
    const bool have_point = result.x.size() == rf.design_size() && result.values.gradient.size() > 0;
    if (have_point) {
        // The optimizer's own result, the last iterate: the point its stop reason describes.
        summary["final_J"] = result.values.f * scale;
        summary["max_violation"] = result.max_violation;
        summary["design"] = std::vector<double>(result.x.data(), result.x.data() + result.x.size());
        write_json((dir / "optimal_problem.json").string(), optimal_problem(now, result.x));
        write_design_vtu((dir / "design_final.vtu").string(), now, now.parameters_of(result.x));
    }
    bool best_differs = false;
    if (result.has_best) {
        const VectorXd& b = result.best_x;
        summary["best_point"] = { { "J", result.best_values.f * scale }, { "max_violation", result.best_max_violation },
            { "evaluation", result.best_evaluation },
            { "iteration",
                result.best_iteration >= 0 ? nlohmann::json(result.best_iteration) : nlohmann::json(nullptr) },
            { "design", std::vector<double>(b.data(), b.data() + b.size()) } };
        // Round-off apart, the last iterate should be the best feasible point the run saw; when it
        // is not, J is not what the optimizer's model of it says (a jump), or the optimizer is
        // non-monotone, and the user must know which of the two points final_J describes.
        const double f = result.values.f, fb = result.best_values.f;
        const bool last_infeasible = result.max_violation > settings.constraint_tolerance;
        best_differs = have_point && b != result.x
            && (f - fb > BEST_POINT_TOLERANCE * std::max({ std::abs(f), std::abs(fb), 1e-300 }) || last_infeasible);
        if (best_differs) {
            write_json((dir / "best_problem.json").string(), optimal_problem(now, b));
            const std::string where = result.best_iteration >= 0
                ? "the iterate of iteration " + std::to_string(result.best_iteration)
                : "a trial point the optimizer did not accept";
            warn("the last iterate is not the best point seen: final_J " + format_number(f * scale)
                + (last_infeasible ? " (outside the constraints by " + format_number(result.max_violation) + ")" : "")
                + " at the last iterate, J " + format_number(fb * scale) + " at evaluation "
                + std::to_string(result.best_evaluation) + " (" + where
                + "); final_J and design are the last iterate's, summary.json's best_point and best_problem.json "
                  "the best point's");
        }
    } else
        summary["best_point"] = nullptr;
    if (!best_differs)
        fs::remove(dir / "best_problem.json", ec); // a resumed run's earlier part may have written one

    // Non-smoothness: accepted steps that J's gradients do not explain (no evaluations), and a
    // short Taylor test at the last iterate (a few).
    nlohmann::json jumps = nlohmann::json::array();
    for (const StepJump& j : result.jumps)
        jumps.push_back({ { "iteration", j.iteration }, { "J_change", j.change * scale },
            { "predicted_change", j.predicted * scale }, { "first_order_scale", j.first_order * scale },
            { "step_norm", j.step_norm } });
    summary["step_check"]
        = { { "steps_checked", result.steps_checked }, { "jumps_found", result.jumps_found }, { "jumps", jumps } };
    if (!result.jumps.empty()) {
        const StepJump& j = result.jumps.front();
        warn(std::to_string(result.jumps_found) + " of " + std::to_string(result.steps_checked)
            + " accepted steps changed J by far more than its gradients predict (largest: J changed by "
            + format_number(j.change * scale) + " over the step to iteration " + std::to_string(j.iteration)
            + ", the gradients at its ends predict " + format_number(j.predicted * scale)
            + "): either J is not smooth along the run (it jumps between designs, e.g. where a contact active set "
              "or the equilibrium changes) or a step went far beyond the range of its first-order model; the "
              "gradient does not describe J over those steps");
    }
    // The keys that come last, and the file (written before the final check's evaluations too).
    const auto write_summary = [&]() {
        summary["warnings"] = warnings;
        if (rf.remesh_settings().enabled()) {
            summary["remeshes"] = remesh_records();
            if (!design_problem.remesh_failure().empty())
                summary["remesh_failure"] = design_problem.remesh_failure();
        }
        const double total_seconds = wall_before + wall.seconds();
        summary["wall_time"] = { { "total", total_seconds }, { "evaluation", result.evaluation_seconds },
            { "optimizer", result.optimizer_seconds } };
        // The optimizer's own CPU time (its thread's, less evaluations and callbacks): unlike the
        // wall time it does not grow while the thread waits for a core on a loaded machine.
        summary["optimizer_cpu_seconds"] = result.optimizer_cpu_seconds;
        // Parts of "evaluation", measured in this process (a resumed run's: since the resume).
        summary["wall_time"]["parametrization"] = design_problem.times().parametrization;
        summary["wall_time"]["validity"] = design_problem.times().validity;
        if (rf.remesh_settings().enabled())
            summary["wall_time"]["remeshing"] = design_problem.remesh_seconds(); // every attempt, used or not
        if (options.distribution)
            summary["processes"] = distribution_summary(*options.distribution);
        write_json((dir / "summary.json").string(), summary);
    };
    summary["final_taylor_check"] = nullptr;
    // Not after a signal (the user wants the run to end) nor after a failure (the problem may
    // not evaluate there any more: a remesh that could not be evaluated).
    if (have_point && settings.final_taylor_check.enabled && stopped_by == 0 && result.reason != StopReason::FAILED
        && result.reason != StopReason::INVALID_START) {
        // The run is over: its summary is on disk before the check's evaluations, whatever ends them.
        write_summary();
        catch_stop_signals(); // a signal now ends the check, not the summary
        try {
            const TaylorCheck check
                = final_taylor_check(design_problem, result.x, result.values, settings.lower, settings.upper,
                    design_scales(now, result.x), settings.final_taylor_check, [] { return stop_signal() != 0; });
            record_taylor_check(check, settings.final_taylor_check, scale, summary, options.quiet);
            if (check.verdict == "non_smooth")
                warn("final Taylor check at the last iterate: " + check.reason);
        } catch (const std::exception& e) {
            // The run's result stands; only the check is lost.
            summary["final_taylor_check"]
                = { { "verdict", "inconclusive" }, { "reason", std::string("the check failed: ") + e.what() },
                      { "seed", settings.final_taylor_check.seed } };
            warn(std::string("final Taylor check at the last iterate failed: ") + e.what());
        }
        stopped_by = release_stop_signals();
    }
    write_summary();

    if (!options.quiet)
        std::printf("diffipc: %s after %d iterations (%d evaluations, %d rejected): J %.6e -> %.6e; wrote %s\n",
            to_string(result.reason).c_str(), result.iterations, result.evaluations, result.rejected, initial_value,
            have_point ? result.values.f * scale : std::nan(""), out_dir.c_str());
    if (stopped_by != 0)
        return interrupted_exit_code(stopped_by);
    if (result.reason == StopReason::INVALID_START || result.reason == StopReason::FAILED) {
        std::fprintf(stderr, "diffipc: %s: %s%s\n", to_string(result.reason).c_str(), result.message.c_str(),
            rejection.empty() ? "" : (" (" + rejection + ")").c_str());
        return 2;
    }
    return 0;
}

} // namespace diffipc
