// diffipc sweep: a problem or scene run at many points of its parameters, over the ranks of a job.

#include "cli/sweep.hpp"

#include "cli/json_path.hpp"

#include "cli/optimize.hpp"
#include "cli/simulate.hpp"

#include "adjoint/adjoint.hpp"
#include "forward/common/error.hpp"
#include "forward/common/timer.hpp"
#include "forward/io/output.hpp"
#include "forward/io/replace_file.hpp"
#include "forward/scene/json_field.hpp"
#include "forward/scene/json_input.hpp"
#include "forward/scene/scene.hpp"
#include "shape_opt/communicator.hpp"
#include "shape_opt/reduced_functional.hpp"
#include "shape_opt/remesh.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>

namespace fs = std::filesystem;
using nlohmann::json;

namespace diffipc {

namespace {

    enum class RunKind { OPTIMIZE, EVALUATE, SIMULATE };

    struct Run {
        size_t index = 0, point = 0;
        int repetition = 0;
        json values = json::object(); ///< path -> value of this point
        json document; ///< the problem or scene with the point's values
    };

    struct Sweep {
        RunKind kind = RunKind::OPTIMIZE;
        std::vector<std::string> paths; ///< the varied paths, in column order
        std::vector<Run> runs;
        std::string out_dir;
    };

    std::string to_string(RunKind kind)
    {
        return kind == RunKind::OPTIMIZE ? "optimize" : kind == RunKind::EVALUATE ? "evaluate" : "simulate";
    }

    Sweep parse_sweep(const std::string& path, const std::string& device)
    {
        const json doc = parse_json_text(read_input_file(path, "sweep file"), path);
        const JsonField root(doc, "");
        if (!doc.is_object())
            throw InputError(path, "a sweep file is a JSON object");
        root.require_object({ "description", "problem", "scene", "run", "grid", "points", "repeat", "output" });
        const fs::path folder = fs::path(path).parent_path().empty() ? fs::path(".") : fs::path(path).parent_path();
        if (root.has("problem") == root.has("scene"))
            root.fail(
                "give exactly one of \"problem\" (a problem file or object) and \"scene\" (a scene file or object)");
        Sweep s;
        json base;
        if (root.has("problem")) {
            const JsonField p = root["problem"];
            const ReducedFunctional rf = p.json().is_string()
                ? ReducedFunctional::load((folder / p.string()).string(), device)
                : ReducedFunctional(p.json(), folder.string(), "problem", device);
            base = self_contained_document(rf); // scenes inlined, paths absolute: it loads from any folder
            s.kind = RunKind::OPTIMIZE;
        } else {
            const JsonField sc = root["scene"];
            fs::path scene_folder = folder;
            if (sc.json().is_string()) {
                const fs::path file = folder / sc.string();
                base = parse_json_text(read_input_file(file.string(), "scene file"), file.string());
                scene_folder = file.parent_path().empty() ? fs::path(".") : file.parent_path();
            } else
                base = sc.json();
            absolute_mesh_paths(base, scene_folder.string());
            s.kind = RunKind::SIMULATE;
        }
        if (root.has("run")) {
            const std::string run = root["run"].string();
            const bool problem = root.has("problem");
            if (problem && run == "optimize")
                s.kind = RunKind::OPTIMIZE;
            else if (problem && run == "evaluate")
                s.kind = RunKind::EVALUATE;
            else if (!problem && run == "simulate")
                s.kind = RunKind::SIMULATE;
            else
                root["run"].fail(problem ? "\"optimize\" or \"evaluate\" for a problem" : "\"simulate\" for a scene");
        }
        const int repeat = root.has("repeat") ? root["repeat"].integer(1) : 1;
        // The points: a list of {path: value}, or the grid's product (keys in alphabetical order, the last fastest).
        std::vector<json> points;
        if (root.has("grid") == root.has("points"))
            root.fail("give exactly one of \"grid\" ({path: [values]}) and \"points\" ([{path: value}])");
        if (root.has("grid")) {
            const JsonField grid = root["grid"];
            if (!grid.is_object() || grid.size() == 0)
                grid.fail("an object {path: [values, ...]} with at least one path");
            points.push_back(json::object());
            for (const auto& [key, values] : grid.json().items()) {
                grid[key].require_array(1);
                s.paths.push_back(key);
                std::vector<json> next;
                for (const json& p : points)
                    for (const json& v : values) {
                        json q = p;
                        q[key] = v;
                        next.push_back(q);
                    }
                points = std::move(next);
            }
        } else {
            const JsonField list = root["points"];
            list.require_array(1);
            for (size_t k = 0; k < list.size(); ++k) {
                const JsonField point = list.at(k);
                if (!point.is_object() || point.size() == 0)
                    point.fail("an object {path: value, ...} with at least one path");
                for (const auto& [key, value] : point.json().items())
                    if (std::find(s.paths.begin(), s.paths.end(), key) == s.paths.end())
                        s.paths.push_back(key);
                points.push_back(point.json());
            }
        }
        // Every point's document now, so that a bad path stops the sweep before any run; the first point with a
        // path is loaded as its run will be (a misspelt key is an unknown key there).
        std::vector<std::string> loaded;
        for (size_t k = 0; k < points.size(); ++k) {
            const std::string point_field = root.has("grid") ? "grid" : "points[" + std::to_string(k) + "]";
            json document = base;
            bool new_path = false;
            for (const auto& [key, value] : points[k].items()) {
                set_path(document, key, value, point_field + "." + key);
                absolute_paths(document, folder);
                if (std::find(loaded.begin(), loaded.end(), key) == loaded.end()) {
                    loaded.push_back(key);
                    new_path = true;
                }
            }
            if (new_path) {
                try {
                    if (s.kind == RunKind::SIMULATE)
                        parse_scene(document, folder.string(), point_field);
                    else
                        ReducedFunctional(document, folder.string(), point_field, device);
                } catch (const InputError& e) {
                    throw InputError(point_field, e.what());
                }
            }
            for (int r = 0; r < repeat; ++r)
                s.runs.push_back({ s.runs.size(), k, r, points[k], document });
        }
        if (root.has("output")) {
            const JsonField out = root["output"];
            out.require_object({ "directory" });
            if (out.has("directory"))
                s.out_dir = (folder / out["directory"].string()).string();
        }
        if (s.out_dir.empty())
            s.out_dir = (fs::path("output") / fs::path(path).stem()).string();
        return s;
    }

    std::string run_folder(const Sweep& s, const Run& run)
    {
        const int width = int(std::to_string(s.runs.size() - 1).size());
        char name[64];
        std::snprintf(name, sizeof name, "run_%0*zu", width, run.index);
        return (fs::path(s.out_dir) / name).string();
    }

    json read_json_file(const fs::path& path)
    {
        std::ifstream in(path);
        json j = json::parse(in, nullptr, false);
        return j.is_discarded() ? json() : j;
    }

    /// One run in its folder: its row (status, exit code, seconds, results, message).
    json execute(const Sweep& s, const Run& run, const std::string& device, int rank)
    {
        const fs::path dir = run_folder(s, run);
        const bool problem = s.kind != RunKind::SIMULATE;
        const std::string input = (dir / (problem ? "problem.json" : "scene.json")).string();
        json row = { { "run", run.index }, { "point", run.point }, { "repetition", run.repetition }, { "rank", rank },
            { "folder", dir.filename().string() }, { "values", run.values } };
        const Timer timer;
        int code = 0;
        std::string message;
        // The command's options for this run: its input and folder, quiet, the sweep's device.
        const auto in_folder = [&](auto options) {
            options.out_dir = dir.string();
            options.quiet = true;
            options.device = device;
            return options;
        };
        try {
            fs::create_directories(dir);
            write_json(input, run.document);
            if (s.kind == RunKind::OPTIMIZE) {
                OptimizeOptions o;
                o.problem_path = input;
                code = optimize(in_folder(o));
                const json summary = read_json_file(dir / "summary.json");
                for (const char* key : { "stop_reason", "iterations", "evaluations", "initial_J", "final_J" })
                    if (summary.contains(key))
                        row[key] = summary[key];
                if (summary.contains("message") && code != 0)
                    message = summary["message"].get<std::string>();
            } else if (s.kind == RunKind::EVALUATE) {
                const ReducedFunctional rf = ReducedFunctional::load(input, device);
                const VectorXd p = rf.parameters_of(rf.design_initial());
                const Evaluation e = rf.evaluate(p, true, !rf.constraints().empty());
                row["J"] = e.value;
                row["gradient_norm"] = e.gradient.norm();
                row["forward_seconds"] = e.forward_time;
                row["adjoint_seconds"] = e.adjoint_time;
                write_json((dir / "evaluation.json").string(),
                    { { "J", e.value },
                        { "gradient", std::vector<double>(e.gradient.data(), e.gradient.data() + e.gradient.size()) },
                        { "constraint_values",
                            std::vector<double>(
                                e.constraint_values.data(), e.constraint_values.data() + e.constraint_values.size()) },
                        { "forward_seconds", e.forward_time }, { "adjoint_seconds", e.adjoint_time } });
            } else {
                SimulateOptions o;
                o.scene_path = input;
                code = simulate(in_folder(o));
                const json summary = read_json_file(dir / "summary.json");
                if (summary.contains("status"))
                    row["status_of_run"] = summary["status"];
                if (summary.contains("steps_committed"))
                    row["steps_committed"] = summary["steps_committed"];
                if (summary.contains("counts") && summary["counts"].contains("newton_iterations"))
                    row["newton_iterations"] = summary["counts"]["newton_iterations"];
                if (summary.contains("failure") && summary["failure"].is_string())
                    message = summary["failure"].get<std::string>();
            }
        } catch (const InputError& e) {
            code = 1;
            message = e.what();
        } catch (const AdjointError& e) {
            code = 2;
            message = e.what();
        } catch (const std::exception& e) {
            code = 3;
            message = e.what();
        }
        row["seconds"] = timer.seconds();
        row["exit_code"] = code;
        row["status"] = code == 0 ? "ok" : code == 1 ? "error" : code >= 128 ? "interrupted" : "failed";
        row["message"] = message;
        return row;
    }

    std::string csv_field(const json& v)
    {
        std::string text = v.is_string() ? v.get<std::string>() : v.is_null() ? "" : v.dump();
        if (text.find_first_of(",\"\n") == std::string::npos)
            return text;
        std::string quoted = "\"";
        for (const char c : text)
            quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
        return quoted + "\"";
    }

    void write_table(const Sweep& s, const std::string& sweep_path, const std::vector<json>& rows)
    {
        std::vector<std::string> results;
        if (s.kind == RunKind::OPTIMIZE)
            results = { "stop_reason", "iterations", "evaluations", "initial_J", "final_J" };
        else if (s.kind == RunKind::EVALUATE)
            results = { "J", "gradient_norm", "forward_seconds", "adjoint_seconds" };
        else
            results = { "status_of_run", "steps_committed", "newton_iterations" };
        // The path "" (a whole document per point) has no column: its values are in sweep.json.
        std::vector<std::string> columns;
        for (const std::string& p : s.paths)
            if (!p.empty())
                columns.push_back(p);
        std::string csv = "run,point,repetition,rank,folder";
        for (const std::string& p : columns)
            csv += "," + csv_field(p);
        csv += ",status,exit_code,seconds";
        for (const std::string& r : results)
            csv += "," + r;
        csv += ",message\n";
        for (const json& row : rows) {
            csv += row["run"].dump() + "," + row["point"].dump() + "," + row["repetition"].dump() + ","
                + row["rank"].dump() + "," + csv_field(row["folder"]);
            for (const std::string& p : columns)
                csv += "," + csv_field(row["values"].contains(p) ? row["values"][p] : json());
            csv += "," + csv_field(row["status"]) + "," + row["exit_code"].dump() + "," + row["seconds"].dump();
            for (const std::string& r : results)
                csv += "," + csv_field(row.contains(r) ? row[r] : json());
            csv += "," + csv_field(row["message"]) + "\n";
        }
        const fs::path dir = s.out_dir;
        write_replacing((dir / "sweep.csv").string(), [&](std::ostream& out) { out << csv; });
        write_json((dir / "sweep.json").string(),
            { { "sweep", fs::absolute(sweep_path).lexically_normal().string() }, { "run", to_string(s.kind) },
                { "paths", s.paths }, { "runs", rows } });
    }

} // namespace

int sweep(const SweepOptions& options, const std::shared_ptr<Communicator>& communicator)
{
    const Sweep s = [&] {
        Sweep parsed = parse_sweep(options.path, options.device);
        if (!options.out_dir.empty())
            parsed.out_dir = options.out_dir;
        return parsed;
    }();
    const int rank = communicator ? communicator->rank() : 0;
    const int size = communicator ? communicator->size() : 1;
    if (rank == 0)
        fs::create_directories(s.out_dir);
    if (!options.quiet && rank == 0)
        std::printf("%s: %zu runs (%s) over %d rank%s into %s\n", options.path.c_str(), s.runs.size(),
            to_string(s.kind).c_str(), size, size == 1 ? "" : "s", s.out_dir.c_str());
    std::vector<json> mine;
    bool interrupted = false;
    for (const Run& run : s.runs) {
        if (int(run.index % size_t(size)) != rank || interrupted)
            continue;
        const fs::path row_path = fs::path(run_folder(s, run)) / "row.json";
        // A run done before (the same command, device and document) keeps its row: an interrupted sweep goes on.
        const json input = { { "run", to_string(s.kind) }, { "device", options.device }, { "document", run.document } };
        const json done = read_json_file(row_path);
        if (done.is_object() && done.contains("input") && done["input"] == input) {
            json row = done;
            row.erase("input");
            mine.push_back(row);
            continue;
        }
        json row = execute(s, run, options.device, rank);
        if (row["status"] == "interrupted") {
            interrupted = true; // the run's own outputs say how far it got; its row is not kept
            mine.push_back(row);
            continue;
        }
        json stored = row;
        stored["input"] = input;
        try {
            write_json(row_path.string(), stored);
        } catch (const std::exception& e) { // the run is done; only its record is not (it runs again next time)
            row["message"] = row["message"].get<std::string>() + (row["message"].get<std::string>().empty() ? "" : "; ")
                + "row.json not written: " + e.what();
        }
        if (!options.quiet && rank == 0)
            std::printf("run %zu of %zu: %s (%.2f s)%s%s\n", run.index + 1, s.runs.size(),
                row["status"].get<std::string>().c_str(), row["seconds"].get<double>(),
                row["message"].get<std::string>().empty() ? "" : ": ", row["message"].get<std::string>().c_str());
        mine.push_back(row);
    }
    // Rank 0 gathers every rank's rows and writes the table; every rank returns its exit code.
    std::vector<json> rows;
    if (communicator && size > 1) {
        const std::vector<std::string> all = communicator->gather(json(mine).dump());
        for (const std::string& text : all)
            for (const json& row : json::parse(text))
                rows.push_back(row);
    } else
        rows = mine;
    std::string verdict = "0", table_error;
    if (rank == 0) {
        std::sort(rows.begin(), rows.end(), [](const json& a, const json& b) { return a["run"] < b["run"]; });
        try {
            write_table(s, options.path, rows);
        } catch (const std::exception& e) { // the other ranks still wait for the verdict
            table_error = e.what();
        }
        int failed = 0, stopped = 0, stop_code = 0;
        for (const json& row : rows) {
            failed += row["status"] != "ok" && row["status"] != "interrupted";
            if (row["status"] == "interrupted") {
                ++stopped;
                stop_code = row["exit_code"].get<int>();
            }
        }
        const int code = stopped ? stop_code : failed ? 2 : 0;
        if (!options.quiet)
            std::printf("diffipc sweep: %zu of %zu runs ok, %d failed%s; wrote %s/sweep.csv\n",
                rows.size() - size_t(failed) - size_t(stopped), s.runs.size(), failed, stopped ? ", stopped" : "",
                s.out_dir.c_str());
        verdict = table_error.empty() ? std::to_string(code) : "3";
    }
    if (communicator && size > 1)
        communicator->broadcast(verdict);
    if (!table_error.empty())
        throw std::runtime_error("the sweep's table: " + table_error);
    return std::stoi(verdict);
}

} // namespace diffipc
