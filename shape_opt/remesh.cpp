#include "shape_opt/remesh.hpp"

#include "forward/common/error.hpp"
#include "forward/mesh/gmsh_writer.hpp"
#include "forward/scene/json_field.hpp"
#include "forward/scene/json_input.hpp"
#include "shape_opt/parametrization/map_json.hpp"
#include "shape_opt/problem_parameters.hpp"
#include "shape_opt/reduced_functional.hpp"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <map>
#include <thread>

extern char** environ;

namespace fs = std::filesystem;

namespace diffipc {

RemeshSettings parse_remesh_settings(const JsonField& f)
{
    f.require_object({ "quality", "size", "max", "surface" });
    RemeshSettings s;
    s.quality = f["quality"].number();
    if (!(s.quality > 0 && s.quality < 1))
        f["quality"].fail("must lie in (0, 1): the worst element's mean ratio below which the mesh is renewed");
    if (f.has("size"))
        s.size = f["size"].positive();
    if (f.has("max"))
        s.max_remeshes = f["max"].integer(0);
    if (f.has("surface")) {
        const std::string surface = f["surface"].string();
        if (surface != "remesh" && surface != "keep")
            f["surface"].fail("expected \"remesh\" or \"keep\", got '" + surface + "'");
        s.remesh_surface = surface == "remesh";
    }
    return s;
}

namespace {

    std::string find_vertices(const nlohmann::json& j, const std::string& path)
    {
        if (j.is_object()) {
            for (const auto& [key, value] : j.items()) {
                const std::string here = path.empty() ? key : path + "." + key;
                if (key == "vertices" && value.is_array())
                    return here;
                if (std::string found = find_vertices(value, here); !found.empty())
                    return found;
            }
        } else if (j.is_array())
            for (size_t i = 0; i < j.size(); ++i)
                if (std::string found = find_vertices(j[i], path + "[" + std::to_string(i) + "]"); !found.empty())
                    return found;
        return "";
    }

} // namespace

std::string vertex_selection(const nlohmann::json& problem)
{
    for (const char* key : { "objective", "constraints", "parameters" })
        if (problem.contains(key))
            if (std::string found = find_vertices(problem[key], key); !found.empty())
                return found;
    if (problem.contains("scenes") && problem["scenes"].is_array())
        for (size_t i = 0; i < problem["scenes"].size(); ++i)
            if (problem["scenes"][i].is_object() && problem["scenes"][i].contains("objective"))
                if (std::string found
                    = find_vertices(problem["scenes"][i]["objective"], "scenes[" + std::to_string(i) + "].objective");
                    !found.empty())
                    return found;
    return "";
}

double element_quality(const Positions& x, const MatrixXi& elements, Index e)
{
    const int n = int(elements.cols());
    double edges = 0;
    for (int a = 0; a < n; ++a)
        for (int b = a + 1; b < n; ++b)
            edges += (x.row(elements(e, a)) - x.row(elements(e, b))).squaredNorm();
    if (!(edges > 0))
        return 0;
    const double size = std::max(0.0, signed_volume(x, elements, e));
    if (n == 3)
        return 4 * std::sqrt(3.0) * size / edges;
    return 12 * std::pow(3 * size, 2.0 / 3.0) / edges;
}

double min_quality(const Positions& x, const MatrixXi& elements)
{
    double q = 1;
    for (Index e = 0; e < elements.rows(); ++e)
        q = std::min(q, element_quality(x, elements, e));
    return q;
}

double mean_edge_length(const Positions& x, const MatrixXi& elements)
{
    double sum = 0;
    Index count = 0;
    for (Index e = 0; e < elements.rows(); ++e)
        for (Index a = 0; a < elements.cols(); ++a)
            for (Index b = a + 1; b < elements.cols(); ++b, ++count)
                sum += (x.row(elements(e, a)) - x.row(elements(e, b))).norm();
    return count > 0 ? sum / double(count) : 0.0;
}

namespace {

    /// The remesher program: $DIFFIPC_GMSH_REMESHER, else the one built with this library.
    std::string remesher_path()
    {
        const char* from_environment = std::getenv("DIFFIPC_GMSH_REMESHER");
        return from_environment && *from_environment ? from_environment : DIFFIPC_GMSH_REMESHER;
    }

    /// The last line of `path` that holds "Error" (gmsh's message before it ended), or "".
    std::string last_error_line(const std::string& path)
    {
        std::ifstream in(path);
        std::string line, found;
        while (std::getline(in, line))
            if (line.find("Error") != std::string::npos)
                found = line;
        return found;
    }

    /// Runs the remesher on IN, OUT with its output in LOG; kills it after `seconds`.
    void run_remesher(const std::string& in, const std::string& out, const std::string& log, double seconds)
    {
        const std::string program = remesher_path();
        posix_spawn_file_actions_t actions;
        posix_spawn_file_actions_init(&actions);
        posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        posix_spawn_file_actions_adddup2(&actions, 1, 2);
        // Not the run's open files (history.h5, ...), and not the terminal's Ctrl-C: the run
        // decides when to stop, and kills the remesher then.
        posix_spawn_file_actions_addclosefrom_np(&actions, 3);
        posix_spawnattr_t attributes;
        posix_spawnattr_init(&attributes);
        posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETPGROUP);
        posix_spawnattr_setpgroup(&attributes, 0);
        std::vector<char*> args { const_cast<char*>(program.c_str()), const_cast<char*>(in.c_str()),
            const_cast<char*>(out.c_str()), nullptr };
        pid_t pid = 0;
        const int spawned = posix_spawn(&pid, program.c_str(), &actions, &attributes, args.data(), environ);
        posix_spawn_file_actions_destroy(&actions);
        posix_spawnattr_destroy(&attributes);
        if (spawned != 0)
            throw RemeshError("cannot run the remesher '" + program + "' (" + std::strerror(spawned)
                + "); set DIFFIPC_GMSH_REMESHER to diffipc-gmsh-remesh of the build");
        const auto start = std::chrono::steady_clock::now();
        int status = 0;
        while (true) {
            const pid_t done = waitpid(pid, &status, WNOHANG);
            if (done == pid)
                break;
            if (done < 0 && errno != EINTR)
                throw RemeshError("lost the remesher process");
            if (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() > seconds) {
                kill(pid, SIGKILL);
                waitpid(pid, &status, 0);
                throw RemeshError("gmsh did not finish within " + format_number(seconds) + " s");
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(2));
        }
        if (WIFEXITED(status) && WEXITSTATUS(status) > 1)
            throw RemeshError("the remesher exited with status " + std::to_string(WEXITSTATUS(status)));
        if (WIFSIGNALED(status)) {
            const std::string gmsh = last_error_line(log);
            throw RemeshError("gmsh ended with signal " + std::to_string(WTERMSIG(status))
                + (gmsh.empty() ? std::string() : " (" + gmsh + ")"));
        }
    }

} // namespace

Mesh remesh_domain(
    const Positions& x, const MatrixXi& boundary, int dim, double size, bool remesh_surface, double seconds)
{
    if (!(size > 0) || !std::isfinite(size))
        throw RemeshError("the target size must be positive");
    if (boundary.rows() == 0 || boundary.cols() != dim || x.cols() != dim)
        throw RemeshError("no boundary to mesh");
    // The remesher's files, unique per process and call.
    static std::atomic<int> calls { 0 };
    const std::string stem
        = (fs::temp_directory_path() / ("diffipc_remesh_" + std::to_string(::getpid()) + "_" + std::to_string(calls++)))
              .string();
    const std::string in_path = stem + "_in.txt", out_path = stem + "_out.txt", log_path = stem + "_log.txt";
    struct Cleanup { // the remesher's files go on every path out of here
        std::vector<std::string> paths;
        ~Cleanup()
        {
            for (const std::string& path : paths)
                std::remove(path.c_str());
        }
    } cleanup { { in_path, out_path, log_path } };
    {
        std::ofstream in(in_path);
        in << std::setprecision(17) << dim << " " << size << " " << (remesh_surface ? 1 : 0) << " " << x.rows() << " "
           << boundary.rows() << "\n";
        for (Index v = 0; v < x.rows(); ++v)
            for (int a = 0; a < dim; ++a)
                in << x(v, a) << (a + 1 < dim ? " " : "\n");
        for (Index f = 0; f < boundary.rows(); ++f)
            for (int a = 0; a < dim; ++a)
                in << boundary(f, a) << (a + 1 < dim ? " " : "\n");
        if (!in)
            throw RemeshError("cannot write " + in_path);
    }
    std::vector<double> new_points;
    std::vector<int> new_elements;
    run_remesher(in_path, out_path, log_path, seconds);
    std::error_code ec;
    const auto bytes = fs::file_size(out_path, ec);
    std::ifstream out(out_path);
    std::string word;
    out >> word;
    if (ec || !out)
        throw RemeshError("the remesher wrote no result");
    if (word == "error") {
        std::string failure;
        std::getline(out, failure);
        throw RemeshError(failure.size() > 1 ? failure.substr(1) : "gmsh failed");
    }
    if (word != "ok")
        throw RemeshError("the remesher's result does not start with ok or error");
    long long points_count = 0, elements_count = 0;
    out >> points_count >> elements_count;
    // Each number takes at least two bytes: counts beyond the file's size are garbage.
    const long long most = static_cast<long long>(bytes) / 2;
    if (!out || points_count <= 0 || elements_count <= 0 || points_count > most / dim
        || elements_count > most / (dim + 1))
        throw RemeshError("the remesher's result has bad counts");
    new_points.resize(size_t(points_count) * size_t(dim));
    new_elements.resize(size_t(elements_count) * size_t(dim + 1));
    for (double& v : new_points)
        out >> v;
    for (int& v : new_elements)
        out >> v;
    if (!out)
        throw RemeshError("the remesher's output is incomplete");
    for (double v : new_points)
        if (!std::isfinite(v))
            throw RemeshError("the remesher returned a non-finite coordinate");
    for (int v : new_elements)
        if (v < 0 || v >= points_count)
            throw RemeshError("the remesher returned an element with an unknown vertex");
    Mesh mesh;
    mesh.dim = dim;
    const Index nv = Index(new_points.size()) / dim, ne = Index(new_elements.size()) / (dim + 1);
    mesh.rest_positions.resize(nv, dim);
    for (Index v = 0; v < nv; ++v)
        for (int a = 0; a < dim; ++a)
            mesh.rest_positions(v, a) = new_points[size_t(v * dim + a)];
    mesh.elements.resize(ne, dim + 1);
    for (Index e = 0; e < ne; ++e)
        for (int a = 0; a <= dim; ++a)
            mesh.elements(e, a) = new_elements[size_t(e * (dim + 1) + a)];
    for (Index e = 0; e < ne; ++e)
        if (signed_volume(mesh.rest_positions, mesh.elements, e) < 0)
            std::swap(mesh.elements(e, 0), mesh.elements(e, 1));
    mesh.vertex_body = VectorXi::Zero(nv);
    mesh.element_body = VectorXi::Zero(ne);
    compute_boundary(mesh);
    return mesh;
}

void absolute_mesh_paths(nlohmann::json& scene, const std::string& base)
{
    for (const char* list : { "bodies", "obstacles" })
        if (scene.is_object() && scene.contains(list) && scene[list].is_array())
            for (auto& item : scene[list])
                if (item.is_object() && item.contains("mesh") && item["mesh"].is_object()
                    && item["mesh"].contains("file") && item["mesh"]["file"].is_string()) {
                    const fs::path file = item["mesh"]["file"].get<std::string>();
                    if (file.is_relative())
                        item["mesh"]["file"] = fs::absolute(fs::path(base) / file).lexically_normal().string();
                }
}

namespace {

    /// Every load case's scene object of a problem document.
    std::vector<nlohmann::json*> case_scenes(nlohmann::json& doc)
    {
        std::vector<nlohmann::json*> scenes;
        if (doc.contains("scenes"))
            for (auto& c : doc["scenes"])
                scenes.push_back(&c["scene"]);
        else
            scenes.push_back(&doc["scene"]);
        return scenes;
    }

} // namespace

int next_remesh_number(const std::string& directory)
{
    int next = 1;
    std::error_code ec;
    for (fs::directory_iterator it(directory, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string name = it->path().filename().string();
        int n = 0;
        char tail[16] = { 0 };
        if (std::sscanf(name.c_str(), "remesh_%d_bod%15s", &n, tail) == 2 && n >= next)
            next = n + 1;
    }
    return next;
}

nlohmann::json remesh_record_json(const RemeshRecord& r)
{
    const auto list = [](const VectorXd& v) { return std::vector<double>(v.data(), v.data() + v.size()); };
    return { { "iteration", r.iteration }, { "quality_before", r.quality_before }, { "quality_after", r.quality_after },
        { "elements_before", r.elements_before }, { "elements_after", r.elements_after }, { "J_before", r.J_before },
        { "J_after", r.J_after }, { "constraints_before", list(r.constraints_before) },
        { "constraints_after", list(r.constraints_after) }, { "files", r.files }, { "seconds", r.seconds } };
}

RemeshRecord remesh_record_from_json(const nlohmann::json& j, const std::string& field)
{
    try {
        RemeshRecord r;
        r.iteration = j.at("iteration").get<int>();
        r.quality_before = j.at("quality_before").get<double>();
        r.quality_after = j.at("quality_after").get<double>();
        r.elements_before = j.at("elements_before").get<Index>();
        r.elements_after = j.at("elements_after").get<Index>();
        r.J_before = j.at("J_before").get<double>();
        r.J_after = j.at("J_after").get<double>();
        const auto before = j.at("constraints_before").get<std::vector<double>>();
        const auto after = j.at("constraints_after").get<std::vector<double>>();
        r.constraints_before = Eigen::Map<const VectorXd>(before.data(), Index(before.size()));
        r.constraints_after = Eigen::Map<const VectorXd>(after.data(), Index(after.size()));
        r.files = j.at("files").get<std::vector<std::string>>();
        r.seconds = j.at("seconds").get<double>();
        return r;
    } catch (const nlohmann::json::exception&) {
        throw InputError(field, "not a remesh record (docs/optimization.md)");
    }
}

nlohmann::json self_contained_document(const ReducedFunctional& functional)
{
    nlohmann::json doc = functional.document();
    const fs::path base = functional.base_directory().empty() ? fs::path(".") : fs::path(functional.base_directory());
    for (nlohmann::json* scene : case_scenes(doc)) {
        if (scene->is_string()) {
            const fs::path file = base / scene->get<std::string>();
            nlohmann::json inlined = parse_json_text(read_input_file(file.string(), "scene file"), file.string());
            absolute_mesh_paths(inlined, file.parent_path().empty() ? "." : file.parent_path().string());
            *scene = std::move(inlined);
        } else
            absolute_mesh_paths(*scene, base.string());
    }
    return doc;
}

Positions design_rest_positions(const ReducedFunctional& functional, const VectorXd& x)
{
    const int d = functional.scene().dim;
    const VectorXd X = functional.rest_positions_of(functional.parameters_of(x));
    Positions current(X.size() / d, d);
    for (Index v = 0; v < current.rows(); ++v)
        current.row(v) = X.segment(v * d, d).transpose();
    return current;
}

double design_quality(const ReducedFunctional& functional, const VectorXd& x)
{
    return min_quality(design_rest_positions(functional, x), bodies_mesh(functional.scene()).elements);
}

nlohmann::json remeshed_document(const ReducedFunctional& functional, const VectorXd& x, double size,
    const std::string& directory, const std::string& name, double seconds, RemeshRecord& record)
{
    const Scene& scene = functional.scene();
    const int d = scene.dim;
    const Mesh bodies = bodies_mesh(scene);
    const Positions current = design_rest_positions(functional, x);
    record.quality_before = min_quality(current, bodies.elements);
    record.elements_before = bodies.elements.rows();
    record.elements_after = 0;
    record.quality_after = 1;
    record.files.clear();
    nlohmann::json doc = self_contained_document(functional);
    const int body_count = int(scene.bodies.size());
    for (int b = 0; b < body_count; ++b) {
        // The body's boundary facets in a local numbering of its vertices.
        std::map<Index, Index> local;
        std::vector<Index> global;
        std::vector<Index> facets;
        for (Index f = 0; f < bodies.boundary_facets.rows(); ++f) {
            if (bodies.facet_body[f] != b)
                continue;
            for (int a = 0; a < d; ++a) {
                const Index v = bodies.boundary_facets(f, a);
                auto [it, inserted] = local.emplace(v, Index(global.size()));
                if (inserted)
                    global.push_back(v);
                facets.push_back(it->second);
            }
        }
        if (facets.empty())
            throw RemeshError("body " + std::to_string(b) + " has no boundary");
        Positions points(Index(global.size()), d);
        for (size_t i = 0; i < global.size(); ++i)
            points.row(Index(i)) = current.row(global[i]);
        MatrixXi boundary(Index(facets.size()) / d, d);
        for (Index f = 0; f < boundary.rows(); ++f)
            for (int a = 0; a < d; ++a)
                boundary(f, a) = int(facets[size_t(f * d + a)]);
        Mesh fresh = remesh_domain(points, boundary, d, size, functional.remesh_settings().remesh_surface, seconds);
        record.quality_after = std::min(record.quality_after, min_quality(fresh.rest_positions, fresh.elements));
        record.elements_after += fresh.elements.rows();
        // Regions select vertices in the scene's mesh: the old one at the design x = 0 (its
        // reference), the new one at x. They must select the same: the new vertices' reference
        // positions (the pull-back) and their positions at x must lie in the same regions.
        Positions reference;
        try {
            reference = functional.pull_back_shape(x, fresh.rest_positions);
        } catch (const std::runtime_error& e) {
            throw RemeshError(e.what());
        }
        const auto check_region = [&](const BoxRegion& region, const std::string& field, double tolerance) {
            for (Index v = 0; v < reference.rows(); ++v)
                if (region.contains(reference.row(v).transpose(), tolerance)
                    != region.contains(fresh.rest_positions.row(v).transpose(), tolerance))
                    throw RemeshError("the design moves the body across the region of " + field
                        + " (regions select in the rest shape at the design's start, the new mesh's at the "
                          "current design): a remesh would change what it selects");
        };
        for (size_t c = 0; c < functional.load_cases(); ++c) {
            const Scene& sc = functional.scene(c);
            const Eigen::RowVectorXd extent = sc.mesh.rest_positions.topRows(sc.body_vertices).colwise().maxCoeff()
                - sc.mesh.rest_positions.topRows(sc.body_vertices).colwise().minCoeff();
            const double tolerance = 1e-9 * extent.norm();
            for (const DirichletSpec& r : sc.dirichlet)
                if (r.body == b)
                    check_region(r.region, r.field, tolerance);
            for (const NeumannSpec& r : sc.neumann)
                if (r.body == b)
                    check_region(r.region, r.field, tolerance);
        }
        const std::string file = (fs::path(directory) / (name + "_body" + std::to_string(b) + ".msh")).string();
        record.files.push_back(file);
        write_gmsh(file, fresh);
        for (nlohmann::json* s : case_scenes(doc)) {
            nlohmann::json& body = (*s)["bodies"][size_t(b)];
            body["mesh"] = { { "file", fs::absolute(file).lexically_normal().string() } };
            body.erase("scale");
            body.erase("translation");
            body.erase("rotation");
        }
    }
    // A default contact distance is a fraction of the bodies' extent: keep the scene's.
    for (size_t c = 0; c < functional.load_cases(); ++c) {
        nlohmann::json& sc = *case_scenes(doc)[c];
        if (functional.scene(c).contact.enabled) {
            if (!sc.contains("contact") || !sc["contact"].is_object())
                sc["contact"] = nlohmann::json::object();
            if (!sc["contact"].contains("dhat"))
                sc["contact"]["dhat"] = functional.scene(c).contact.dhat;
        }
    }
    // The new meshes are the shape at x: the free-form deformation evaluates its basis at their
    // pull-back ("mesh_at"), so the same x gives the same domain, and the shape entry starts
    // at x.
    try {
        const ShapeLatticeInput in = functional.shape_lattice_input(x);
        nlohmann::json& entry = doc["parameters"][in.entry];
        entry["maps"][in.map][in.mesh_input_key]
            = std::vector<double>(in.lattice.data(), in.lattice.data() + in.lattice.size());
        entry["initial"] = std::vector<double>(in.design.data(), in.design.data() + in.design.size());
    } catch (const std::runtime_error& e) {
        throw RemeshError(e.what());
    }
    return doc;
}

} // namespace diffipc
