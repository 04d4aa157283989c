// diffipc optimize: a problem file's optimization run with its outputs (docs/optimization.md).

#include "cli/optimize.hpp"

#include "cli/stop_signal.hpp"

#include "forward/common/error.hpp"
#include "forward/common/timer.hpp"
#include "forward/io/output.hpp"
#include "forward/io/replace_file.hpp"
#include "forward/io/vtu_writer.hpp"
#include "shape_opt/design_problem.hpp"
#include "shape_opt/optimizer/optimizer_json.hpp"
#include "shape_opt/reduced_functional.hpp"
#include "shape_opt/remesh.hpp"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace fs = std::filesystem;

namespace diffipc {

namespace {

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

    std::string csv_number(double v)
    {
        char text[32];
        std::snprintf(text, sizeof text, "%.17g", v);
        return text;
    }

} // namespace

int optimize(const std::string& problem_path, std::string out_dir, bool quiet)
{
    const Timer wall;
    const ReducedFunctional rf = ReducedFunctional::load(problem_path);
    OptimizerSettings settings = parse_optimizer_settings(JsonField(rf.optimizer_spec(), "optimizer"));
    settings.lower = rf.design_lower();
    settings.upper = rf.design_upper();
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
    std::error_code ec;
    fs::create_directories(out_dir, ec);
    if (ec || !fs::is_directory(out_dir))
        throw InputError(out_dir, "cannot create output directory");

    DesignProblem problem(rf);
    problem.set_remesh_directory(out_dir);
    const auto& constraints = rf.constraints();
    const std::string history_path = (fs::path(out_dir) / "history.csv").string();
    std::ofstream history(history_path);
    if (!history)
        throw InputError(history_path, "cannot write");
    history << "iteration,J";
    for (const ConstraintSpec& c : constraints)
        history << "," << c.name;
    history << ",gradient_norm,step_norm,evaluations,rejected,evaluation_seconds,optimizer_seconds,wall_seconds\n";
    std::vector<PvdEntry> designs;
    if (!quiet) {
        std::printf("diffipc: %s: %ld design variables, %zu constraints, %s\n", problem_path.c_str(),
            long(rf.design_size()), constraints.size(), to_string(settings.algorithm).c_str());
        std::printf("  %4s  %-13s", "iter", "J");
        for (const ConstraintSpec& c : constraints)
            std::printf("  %-12.12s", c.name.c_str());
        std::printf("  %-9s  %-9s  %4s  %8s  %8s\n", "|grad|", "step", "rej", "eval s", "opt s");
    }
    double initial_value = std::nan("");
    problem.on_iteration = [&](const IterationInfo& info) {
        const double J = info.values->f * problem.objective_scale();
        if (info.iteration == 0)
            initial_value = J;
        history << info.iteration << "," << csv_number(J);
        const VectorXd& g = problem.last_constraint_values();
        for (size_t i = 0; i < constraints.size(); ++i)
            history << "," << csv_number(Index(i) < g.size() ? g[Index(i)] : std::nan(""));
        history << "," << csv_number(info.gradient_norm) << "," << csv_number(info.step_norm) << "," << info.evaluations
                << "," << info.rejected << "," << csv_number(info.evaluation_seconds) << ","
                << csv_number(info.optimizer_seconds) << "," << csv_number(wall.seconds()) << "\n";
        history.flush();
        if (!quiet) {
            std::printf("  %4d  %-13.6e", info.iteration, J);
            for (size_t i = 0; i < constraints.size(); ++i)
                std::printf("  %-12.5e", Index(i) < g.size() ? g[Index(i)] : std::nan(""));
            std::printf("  %-9.2e  %-9.2e  %4d  %8.2f  %8.3f\n", info.gradient_norm, info.step_norm, info.rejected,
                info.evaluation_seconds, info.optimizer_seconds);
            std::fflush(stdout);
        }
        if (design_every > 0 && info.iteration % design_every == 0) {
            const std::string name = "design_" + std::to_string(info.iteration) + ".vtu";
            const ReducedFunctional& now = problem.functional();
            write_design_vtu((fs::path(out_dir) / name).string(), now, now.parameters_of(*info.x));
            designs.push_back({ double(info.iteration), 0, name });
            write_pvd((fs::path(out_dir) / "designs.pvd").string(), designs);
        }
        return stop_signal() == 0;
    };
    problem.on_remesh = [&](const RemeshRecord& r) {
        if (!quiet) {
            std::printf("  remeshed after iteration %d: quality %.3f -> %.3f, %ld -> %ld elements, J %.6e -> %.6e "
                        "(%.2f s)\n",
                r.iteration, r.quality_before, r.quality_after, long(r.elements_before), long(r.elements_after),
                r.J_before, r.J_after, r.seconds);
            std::fflush(stdout);
        }
    };

    catch_stop_signals(); // the run stops after the current iteration
    const OptimizerResult result = minimize(problem, rf.design_initial(), settings);
    const int stopped_by = release_stop_signals();
    history.close();

    nlohmann::json summary;
    summary["problem"] = problem_path;
    summary["algorithm"] = to_string(settings.algorithm);
    summary["stop_reason"] = to_string(result.reason);
    summary["message"] = result.message;
    summary["iterations"] = result.iterations;
    summary["evaluations"] = result.evaluations;
    summary["rejected"] = result.rejected;
    if (!problem.last_rejection().empty())
        summary["last_rejection"] = problem.last_rejection();
    if (std::isfinite(initial_value))
        summary["initial_J"] = initial_value;
    const bool have_point = result.x.size() == rf.design_size() && result.values.gradient.size() > 0;
    if (have_point) {
        summary["final_J"] = result.values.f * problem.objective_scale();
        summary["max_violation"] = result.max_violation;
        summary["design"] = std::vector<double>(result.x.data(), result.x.data() + result.x.size());
        const ReducedFunctional& now = problem.functional();
        write_json((fs::path(out_dir) / "optimal_problem.json").string(), optimal_problem(now, result.x));
        write_design_vtu((fs::path(out_dir) / "design_final.vtu").string(), now, now.parameters_of(result.x));
    }
    if (rf.remesh_settings().enabled()) {
        nlohmann::json list = nlohmann::json::array();
        for (const RemeshRecord& r : problem.remeshes())
            list.push_back({ { "iteration", r.iteration }, { "quality_before", r.quality_before },
                { "quality_after", r.quality_after }, { "elements_before", r.elements_before },
                { "elements_after", r.elements_after }, { "J_before", r.J_before }, { "J_after", r.J_after },
                { "constraints_before",
                    std::vector<double>(
                        r.constraints_before.data(), r.constraints_before.data() + r.constraints_before.size()) },
                { "constraints_after",
                    std::vector<double>(
                        r.constraints_after.data(), r.constraints_after.data() + r.constraints_after.size()) },
                { "files", r.files }, { "seconds", r.seconds } });
        summary["remeshes"] = list;
        if (!problem.remesh_failure().empty())
            summary["remesh_failure"] = problem.remesh_failure();
    }
    summary["wall_time"] = { { "total", wall.seconds() }, { "evaluation", result.evaluation_seconds },
        { "optimizer", result.optimizer_seconds } };
    write_json((fs::path(out_dir) / "summary.json").string(), summary);

    if (!quiet)
        std::printf("diffipc: %s after %d iterations (%d evaluations, %d rejected): J %.6e -> %.6e; wrote %s\n",
            to_string(result.reason).c_str(), result.iterations, result.evaluations, result.rejected, initial_value,
            have_point ? result.values.f * problem.objective_scale() : std::nan(""), out_dir.c_str());
    if (stopped_by != 0)
        return interrupted_exit_code(stopped_by);
    if (result.reason == StopReason::INVALID_START || result.reason == StopReason::FAILED) {
        std::fprintf(stderr, "diffipc: %s: %s%s\n", to_string(result.reason).c_str(), result.message.c_str(),
            problem.last_rejection().empty() ? "" : (" (" + problem.last_rejection() + ")").c_str());
        return 2;
    }
    return 0;
}

} // namespace diffipc
