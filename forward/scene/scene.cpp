#include "forward/scene/scene.hpp"

#include "forward/common/error.hpp"
#include "forward/mesh/gmsh_reader.hpp"
#include "forward/scene/json_field.hpp"
#include "forward/scene/json_input.hpp"

#include <Eigen/Geometry>

#include <sys/resource.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <optional>

#include <filesystem>
#include <fstream>
#include <sstream>

namespace diffipc {

double usable_memory_bytes()
{
    double bytes = double(sysconf(_SC_PHYS_PAGES)) * double(sysconf(_SC_PAGE_SIZE));
    if (struct rlimit limit; getrlimit(RLIMIT_AS, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY)
        bytes = std::min(bytes, double(limit.rlim_cur));
    return bytes;
}

std::string to_string(IntegratorType type)
{
    switch (type) {
    case IntegratorType::STATIC:
        return "static";
    case IntegratorType::IMPLICIT_EULER:
        return "implicit_euler";
    case IntegratorType::BDF2:
        return "bdf2";
    case IntegratorType::NEWMARK:
        return "newmark";
    }
    return "unknown";
}

bool BoxRegion::contains(const Eigen::Ref<const VectorXd>& p, double tolerance) const
{
    for (Index a = 0; a < p.size(); ++a)
        if (p[a] < lower[a] - tolerance || p[a] > upper[a] + tolerance)
            return false;
    return true;
}

namespace {

    namespace fs = std::filesystem;

    /// Largest Young's modulus and density accepted: beyond, stresses and forces overflow.
    constexpr double MAX_MATERIAL_VALUE = 1e30;
    /// Smallest time step accepted (s).
    constexpr double MIN_TIME_STEP = 1e-12;

    /// Memory that setting up a simulation takes per element (mesh, FE space, Hessian pattern
    /// and assembly buffers), measured by `diffipc validate` on boxes: about 700 bytes per
    /// triangle and 1,200 per tetrahedron (docs/scene_format.md "Limits"). Slightly below the
    /// measurements, so that no scene that fits is refused; the first factorization needs more.
    double setup_bytes_per_element(int dim) { return dim == 2 ? 600.0 : 1000.0; }

    /// Refuses, naming `field`, a mesh whose elements (with those of the bodies before it)
    /// cannot be set up in this process's memory: before, a 7000 x 7000 box was allocated
    /// until the process died, even in validate.
    void check_memory(const JsonField& field, int dim, double elements, double elements_before)
    {
        const double need = (elements + elements_before) * setup_bytes_per_element(dim);
        const double have = usable_memory_bytes();
        if (have > 0 && need > have) {
            char text[256];
            std::snprintf(text, sizeof text,
                "%.4g elements%s need about %.3g GB to set up, more than the %.3g GB this process may use", elements,
                elements_before > 0 ? " (with the bodies before it)" : "", need * 1e-9, have * 1e-9);
            field.fail(text);
        }
    }

    /// Largest vertex coordinate accepted after placement (m): beyond, the distances that
    /// contact and the broad phase compute lose all their digits (or overflow).
    constexpr double MAX_COORDINATE = 1e12;

    /// Vertices of a body or obstacle after its scale, rotation and translation: finite and
    /// within MAX_COORDINATE, else an InputError naming the body or obstacle.
    void check_placed_coordinates(const MatrixXd& X, const JsonField& owner)
    {
        const double largest = X.size() ? X.cwiseAbs().maxCoeff() : 0.0;
        if (!X.allFinite() || !(largest <= MAX_COORDINATE))
            owner.fail("vertex coordinates after scale, rotation and translation are "
                + std::string(X.allFinite() ? "beyond 1e12 m" : "not finite")
                + " (contact distances would lose every digit)");
    }

    /// Relative change of an element's (or obstacle facet's) size that translation and rotation
    /// may cause by round-off: beyond, the placed geometry has lost more than 6 of its digits.
    constexpr double MAX_PLACEMENT_DISTORTION = 1e-6;

    /// Length, area or volume of the simplex of `cells` row c (k + 1 vertices, k <= dimension),
    /// from the Gram determinant of its edge vectors.
    double simplex_measure(const MatrixXd& X, const MatrixXi& cells, Index c)
    {
        const Index k = cells.cols() - 1;
        MatrixXd edges(X.cols(), k);
        for (Index j = 0; j < k; ++j)
            edges.col(j) = (X.row(cells(c, j + 1)) - X.row(cells(c, 0))).transpose();
        double factorial = 1;
        for (Index j = 2; j <= k; ++j)
            factorial *= double(j);
        return std::sqrt(std::abs((edges.transpose() * edges).determinant())) / factorial;
    }

    /// A rigid placement (rotation, translation) of a mesh with vertices `before` to `after`
    /// keeps every cell's size to MAX_PLACEMENT_DISTORTION; a translation far from the origin
    /// does not (coordinates 1e11 m on a 1 cm element keep 5 digits), and is refused here,
    /// where validate sees it, instead of simulating elements that round-off has deformed.
    void check_placement_keeps_cells(
        const MatrixXd& before, const MatrixXd& after, const MatrixXi& cells, const JsonField& owner)
    {
        for (Index c = 0; c < cells.rows(); ++c) {
            const double m0 = simplex_measure(before, cells, c);
            const double m1 = simplex_measure(after, cells, c);
            if (!(std::abs(m1 - m0) <= MAX_PLACEMENT_DISTORTION * m0))
                owner.fail("its translation or rotation changes the size of "
                    + std::string(cells.cols() > before.cols() ? "element " : "facet ") + std::to_string(c)
                    + " by a relative " + format_number(std::abs(m1 - m0) / m0)
                    + " (round-off: the coordinates are too large for the cell size; move the origin closer)");
        }
    }

    MaterialSpec parse_material(const JsonField& f, int dim)
    {
        f.require_object({ "model", "E", "nu", "density", "plane" });
        MaterialSpec m;
        m.model = parse_material_model(f["model"].string(), f.path() + ".model");
        m.youngs_modulus = f["E"].number();
        if (!(m.youngs_modulus > 0))
            f["E"].fail("Young's modulus must be positive");
        if (m.youngs_modulus > MAX_MATERIAL_VALUE)
            f["E"].fail("Young's modulus above 1e30 Pa: stresses would overflow (are the units consistent?)");
        m.poisson_ratio = f["nu"].number();
        if (!(m.poisson_ratio > -1.0 && m.poisson_ratio < 0.5))
            f["nu"].fail("Poisson's ratio must lie in (-1, 0.5), got " + f["nu"].json().dump());
        m.density = f["density"].positive();
        if (m.density > MAX_MATERIAL_VALUE)
            f["density"].fail(
                "density above 1e30 kg/m^3: masses and forces would overflow (are the units consistent?)");
        if (f.has("plane")) {
            const std::string plane = f["plane"].string();
            if (dim != 2)
                f["plane"].fail("plane stress or strain is a 2D option");
            if (plane != "strain" && plane != "stress")
                f["plane"].fail("expected \"strain\" or \"stress\", got \"" + plane + "\"");
            m.plane_stress = plane == "stress";
        }
        return m;
    }

    /// `elements_before`: the elements of the bodies already read (for the memory estimate).
    Mesh parse_mesh(
        const JsonField& f, int dim, const std::string& base_directory, std::string& source, double elements_before)
    {
        f.require_object({ "box", "file", "annulus", "torus" });
        if (int(f.has("box")) + int(f.has("file")) + int(f.has("annulus")) + int(f.has("torus")) != 1)
            f.fail("give exactly one of \"box\", \"annulus\", \"torus\" or \"file\"");
        Mesh mesh;
        if (f.has("torus")) {
            const JsonField a = f["torus"];
            if (dim != 3)
                a.fail("a torus mesh is 3D only");
            a.require_object({ "major_radius", "half_width", "cells_across", "segments" });
            const double R = a["major_radius"].positive(), w = a["half_width"].positive();
            if (!(w < R))
                a["half_width"].fail("must be below \"major_radius\"");
            const int across = a.has("cells_across") ? a["cells_across"].integer(1) : 1;
            const int segments = a["segments"].integer(3);
            if (double(across) * across * segments > 1e7)
                a["segments"].fail("too many cells");
            check_memory(a["segments"], dim, 6.0 * across * across * segments, elements_before);
            source = "torus";
            mesh = torus_mesh(R, w, across, segments);
        } else if (f.has("annulus")) {
            const JsonField a = f["annulus"];
            if (dim != 2)
                a.fail("an annulus mesh is 2D only");
            a.require_object({ "center", "inner_radius", "outer_radius", "segments", "layers" });
            const VectorXd center = a.has("center") ? a["center"].vector(2) : VectorXd::Zero(2);
            const double r0 = a["inner_radius"].positive(), r1 = a["outer_radius"].positive();
            if (!(r1 > r0))
                a["outer_radius"].fail("must exceed \"inner_radius\"");
            const int segments = a["segments"].integer(3);
            const int layers = a.has("layers") ? a["layers"].integer(1) : 1;
            if (double(segments) * layers > 1e7)
                a["segments"].fail("too many cells");
            check_memory(a["segments"], dim, 2.0 * segments * layers, elements_before);
            source = "annulus";
            mesh = annulus_mesh(center, r0, r1, segments, layers);
        } else if (f.has("box")) {
            const JsonField box = f["box"];
            box.require_object({ "min", "max", "cells" });
            const VectorXd lower = box["min"].vector(dim), upper = box["max"].vector(dim);
            const VectorXi cells = box["cells"].int_vector(dim, 1);
            for (int a = 0; a < dim; ++a)
                if (!(upper[a] > lower[a]))
                    box["max"].fail("must exceed \"min\" in every component");
            if (cells.cast<double>().prod() > 5e7)
                box["cells"].fail("too many cells");
            check_memory(box["cells"], dim, (dim == 2 ? 2.0 : 6.0) * cells.cast<double>().prod(), elements_before);
            source = "box";
            mesh = box_mesh(dim, lower, upper, cells);
        } else {
            fs::path p(f["file"].string());
            if (p.is_relative())
                p = fs::path(base_directory) / p;
            if (std::error_code ec; !fs::is_regular_file(p, ec))
                f["file"].fail(
                    "cannot open mesh file '" + p.string() + "'" + (ec ? " (" + ec.message() + ")" : std::string()));
            const std::string ext = p.extension().string();
            if (ext != ".msh")
                f["file"].fail("unsupported mesh format '" + ext + "' (expected a gmsh .msh file)");
            source = p.string();
            mesh = read_gmsh(p.string(), dim);
            check_memory(f["file"], dim, double(mesh.num_elements()), elements_before);
        }
        validate_mesh(mesh, f.path());
        return mesh;
    }

    int parse_body_reference(const JsonField& f, const std::vector<BodySpec>& bodies)
    {
        if (f.json().is_number_integer()) {
            const int b = f.integer(0);
            if (b >= int(bodies.size()))
                f.fail(
                    "body index " + std::to_string(b) + " out of range (" + std::to_string(bodies.size()) + " bodies)");
            return b;
        }
        const std::string name = f.string();
        for (size_t b = 0; b < bodies.size(); ++b)
            if (bodies[b].name == name)
                return int(b);
        f.fail("no body named '" + name + "'");
    }

    BoxRegion parse_region(const JsonField& f, int dim)
    {
        f.require_object({ "min", "max" });
        BoxRegion r { f["min"].vector(dim), f["max"].vector(dim) };
        for (int a = 0; a < dim; ++a)
            if (r.upper[a] < r.lower[a])
                f["max"].fail("must not be below \"min\" in any component");
        return r;
    }

    Expression parse_expression(const JsonField& f)
    {
        if (f.json().is_number())
            return Expression(f.number());
        if (f.json().is_string())
            return Expression(f.string(), f.path());
        f.fail("expected a number or an expression string");
    }

    /// One expression (or, if allowed, null) per component.
    std::vector<std::optional<Expression>> parse_components(const JsonField& f, int dim, bool allow_null)
    {
        f.require_array();
        if (int(f.size()) != dim)
            f.fail("expected " + std::to_string(dim) + " entries (expression or number"
                + (allow_null ? " or null)" : ")"));
        std::vector<std::optional<Expression>> out;
        for (int a = 0; a < dim; ++a) {
            const JsonField c = f.at(size_t(a));
            if (allow_null && c.json().is_null())
                out.emplace_back(std::nullopt);
            else
                out.emplace_back(parse_expression(c));
        }
        return out;
    }

    double parse_local_friction(const JsonField& f)
    {
        f.require_object({ "coefficient" });
        const double mu = f["coefficient"].number();
        if (mu < 0)
            f["coefficient"].fail("must be >= 0");
        return mu;
    }

    /// Is some friction coefficient (global, a body's or an obstacle's) positive?
    bool any_friction(const Scene& scene)
    {
        bool any = scene.friction.coefficient > 0;
        for (const auto& b : scene.bodies)
            any = any || b.friction_coefficient > 0;
        for (const auto& o : scene.obstacles)
            any = any || o.friction_coefficient > 0;
        return any;
    }

    /// "adaptive": true / false, or an object of the policy's settings (AdaptiveSpec).
    AdaptiveSpec parse_adaptive(const JsonField& f, const TimeSpec& time)
    {
        AdaptiveSpec a;
        if (f.json().is_boolean()) {
            a.enabled = f.boolean();
        } else {
            f.require_object(
                { "min_increment", "cut", "growth", "iteration_target", "displacement_control", "relaxation" });
            a.enabled = true;
            if (f.has("min_increment")) {
                a.min_increment = f["min_increment"].positive();
                if (a.min_increment > time.dt)
                    f["min_increment"].fail("must not exceed time.dt (" + format_number(time.dt) + " s)");
            }
            if (f.has("cut")) {
                a.cut = f["cut"].number();
                if (!(a.cut > 0 && a.cut < 1))
                    f["cut"].fail("must lie in (0, 1), got " + f["cut"].json().dump());
            }
            if (f.has("growth")) {
                a.growth = f["growth"].number();
                if (!(a.growth >= 1 && a.growth <= 10))
                    f["growth"].fail("must lie in [1, 10], got " + f["growth"].json().dump());
            }
            if (f.has("iteration_target"))
                a.iteration_target = f["iteration_target"].integer(1);
            if (f.has("displacement_control"))
                a.displacement_control = f["displacement_control"].boolean();
            if (f.has("relaxation"))
                a.relaxation = f["relaxation"].boolean();
        }
        if (a.enabled && time.integrator == IntegratorType::BDF2)
            f.fail("automatic step control needs a one-step integrator (\"static\", \"implicit_euler\" or "
                   "\"newmark\"): BDF2's two-step formula has no variable-step form here");
        if (a.min_increment == 0)
            a.min_increment = time.dt / 1024;
        return a;
    }

    /// "periodic": the box, its periodic axes, the tolerance, the macro gradient's prescribed and
    /// free components; pairs the bodies' vertices and drops the periodic faces' facets.
    void parse_periodic(const JsonField& f, Scene& scene)
    {
        f.require_object({ "box", "axes", "tolerance", "gradient", "free" });
        const int d = scene.dim;
        PeriodicSpec& p = scene.periodic;
        p.enabled = true;
        const char* names = "xyz";
        const auto rows = scene.mesh.rest_positions.topRows(scene.body_vertices);
        if (f.has("box")) {
            const BoxRegion r = parse_region(f["box"], d);
            p.box.lower = r.lower;
            p.box.upper = r.upper;
        } else {
            p.box.lower = rows.colwise().minCoeff().transpose();
            p.box.upper = rows.colwise().maxCoeff().transpose();
        }
        const double diagonal = (p.box.upper - p.box.lower).norm();
        p.tolerance = f.has("tolerance") ? f["tolerance"].positive() : 1e-9 * diagonal;
        if (f.has("axes")) {
            const JsonField axes = f["axes"];
            axes.require_array(1);
            p.box.periodic = { { false, false, false } };
            for (size_t i = 0; i < axes.size(); ++i) {
                const std::string a = axes.at(i).string();
                const char* at = a.size() == 1 ? std::strchr(names, a[0]) : nullptr;
                if (!at || at - names >= d)
                    axes.at(i).fail("expected one of " + std::string(names, size_t(d)) + ", got \"" + a + "\"");
                p.box.periodic[size_t(at - names)] = true;
            }
        } else {
            p.box.periodic = { { true, true, d == 3 } };
        }
        // G: prescribed entries (default 0), and the free ones.
        p.gradient.assign(size_t(d * d), Expression(0.0));
        if (f.has("gradient")) {
            const JsonField g = f["gradient"];
            g.require_array();
            if (int(g.size()) != d)
                g.fail("expected " + std::to_string(d) + " rows of " + std::to_string(d) + " entries");
            for (int i = 0; i < d; ++i) {
                const auto row = parse_components(g.at(size_t(i)), d, true); // null: free
                for (int j = 0; j < d; ++j)
                    p.gradient[size_t(i * d + j)] = row[size_t(j)];
            }
        }
        if (f.has("free")) {
            const JsonField free = f["free"];
            free.require_array();
            for (size_t k = 0; k < free.size(); ++k) {
                const std::string c = free.at(k).string();
                const char* i = c.size() == 2 ? std::strchr(names, c[0]) : nullptr;
                const char* j = c.size() == 2 ? std::strchr(names, c[1]) : nullptr;
                if (!i || !j || i - names >= d || j - names >= d)
                    free.at(k).fail(
                        "expected a component such as \"xx\" or \"yx\" (row, column of G), got \"" + c + "\"");
                const int a = int(i - names), b = int(j - names);
                if (f.has("gradient") && !f["gradient"].at(size_t(a)).at(size_t(b)).json().is_null())
                    free.at(k).fail("G_" + c + " is both prescribed (" + f["gradient"].path() + "[" + std::to_string(a)
                        + "][" + std::to_string(b) + "]) and free");
                p.gradient[size_t(a * d + b)] = std::nullopt;
            }
        }
        // Free components (null in "gradient" or listed in "free"): not along a non-periodic axis,
        // and not both of a symmetric pair.
        const auto fail_free = [&f](const std::string& message) {
            (f.has("free") ? f["free"] : f["gradient"]).fail(message); // one of them made it free
        };
        for (int a = 0; a < d; ++a)
            for (int b = 0; b < d; ++b) {
                if (p.gradient[size_t(a * d + b)])
                    continue;
                const std::string c = std::string("G_") + names[a] + names[b];
                if (!p.box.periodic[size_t(b)])
                    fail_free(c + " multiplies the non-periodic axis " + std::string(1, names[b])
                        + ": the fluctuation carries it, so it cannot be free");
                if (b > a && !p.gradient[size_t(b * d + a)])
                    fail_free(c + " and G_" + names[b] + names[a]
                        + " are both free: a rigid rotation of the cell would be free too (prescribe one)");
            }
        // Not built yet for periodic cells: say so, naming the field.
        if (!scene.obstacles.empty())
            f.fail("obstacles in a periodic cell are not supported");
        if (!scene.dirichlet.empty())
            f.fail("Dirichlet conditions in a periodic cell are not supported: prescribe the macro gradient");
        if (scene.time.adaptive.enabled)
            f.fail("time.adaptive in a periodic cell is not built yet");
        p.pairing = pair_periodic_vertices(
            scene.mesh, p.box, p.tolerance, scene.bodies.size() == 1 ? "bodies[0].mesh" : "bodies");
        remove_periodic_facets(scene.mesh, p.box, p.tolerance);
    }

    void parse_friction(const JsonField& root, Scene& scene)
    {
        FrictionSpec& fr = scene.friction;
        if (root.has("friction")) {
            const JsonField f = root["friction"];
            f.require_object({ "coefficient", "eps_v", "iterations", "policy" });
            if (f.has("coefficient")) {
                fr.coefficient = f["coefficient"].number();
                if (fr.coefficient < 0)
                    f["coefficient"].fail("must be >= 0");
            }
            if (f.has("eps_v"))
                fr.eps_v = f["eps_v"].positive();
            if (f.has("iterations"))
                fr.iterations = f["iterations"].integer(1);
            if (f.has("policy")) {
                const std::string p = f["policy"].string();
                if (p != "permissive" && p != "strict")
                    f["policy"].fail("expected \"permissive\" or \"strict\"");
                fr.strict = p == "strict";
            }
        }
        if (any_friction(scene) && !scene.contact.enabled)
            root[root.has("friction") ? "friction" : "bodies"].fail(
                "friction needs contact (a \"contact\" block or obstacles)");
    }

    void parse_contact(const JsonField& root, Scene& scene)
    {
        const Eigen::RowVectorXd extent
            = scene.mesh.rest_positions.colwise().maxCoeff() - scene.mesh.rest_positions.colwise().minCoeff();
        ContactSpec& c = scene.contact;
        c.dhat = 1e-3 * extent.norm();
        if (!root.has("contact"))
            return;
        const JsonField f = root["contact"];
        f.require_object({ "enabled", "dhat", "kappa", "self_contact", "min_distance", "ccd_max_iterations",
            "ccd_rescaling", "model", "penalty_stiffness" });
        c.enabled = f.has("enabled") ? f["enabled"].boolean() : true;
        if (f.has("dhat")) {
            c.dhat = f["dhat"].positive();
            if (!(c.dhat <= MAX_COORDINATE))
                f["dhat"].fail(
                    "must be at most 1e12 m (the largest coordinate accepted), got " + format_number(c.dhat));
        }
        if (f.has("kappa")) {
            const JsonField k = f["kappa"];
            if (k.json().is_string()) {
                if (k.string() != "adaptive")
                    k.fail("expected a positive number or \"adaptive\"");
                c.adaptive_kappa = true;
            } else {
                c.adaptive_kappa = false;
                c.kappa = k.positive();
            }
        }
        if (f.has("self_contact"))
            c.self_contact = f["self_contact"].boolean();
        if (f.has("min_distance")) {
            c.min_distance = f["min_distance"].number();
            if (c.min_distance < 0)
                f["min_distance"].fail("must be >= 0");
        }
        if (f.has("ccd_max_iterations"))
            c.ccd_max_iterations = f["ccd_max_iterations"].integer(1);
        if (f.has("ccd_rescaling")) {
            c.ccd_rescaling = f["ccd_rescaling"].number();
            if (!(c.ccd_rescaling > 0 && c.ccd_rescaling < 1))
                f["ccd_rescaling"].fail("must lie in (0, 1)");
        }
        const std::string model = f.has("model") ? f["model"].string() : "ipc";
        if (model != "ipc" && model != "penalty")
            f["model"].fail("expected \"ipc\" or \"penalty\", got \"" + model + "\"");
        c.penalty = model == "penalty";
        if (c.penalty) {
            // The penalty's stiffness is its own parameter (N/m), not a barrier stiffness.
            if (f.has("kappa"))
                f["kappa"].fail("is the barrier's stiffness; penalty contact takes \"penalty_stiffness\" (N/m)");
            if (!f.has("penalty_stiffness"))
                f.fail("\"model\": \"penalty\" needs \"penalty_stiffness\" (N/m)");
            c.kappa = f["penalty_stiffness"].positive();
            c.adaptive_kappa = false;
            if (c.min_distance > 0)
                f["min_distance"].fail("penalty contact has no minimum separation (the penalty allows penetration)");
            for (const char* key : { "ccd_max_iterations", "ccd_rescaling" })
                if (f.has(key))
                    f[key].fail("penalty contact uses no CCD");
        } else if (f.has("penalty_stiffness"))
            f["penalty_stiffness"].fail("is for \"model\": \"penalty\"");
    }

    void parse_obstacles(const JsonField& root, const std::string& base_directory, Scene& scene)
    {
        if (!root.has("obstacles"))
            return;
        const int dim = scene.dim;
        const JsonField list = root["obstacles"];
        list.require_array();
        for (size_t i = 0; i < list.size(); ++i) {
            const JsonField f = list.at(i);
            f.require_object({ "name", "plane", "mesh", "friction" });
            if (f.has("plane") == f.has("mesh"))
                f.fail("give exactly one of \"plane\" or \"mesh\"");
            ObstacleSpec o;
            o.field = f.path();
            if (f.has("friction"))
                o.friction_coefficient = parse_local_friction(f["friction"]);
            o.name = f.has("name") ? f["name"].string() : "obstacle" + std::to_string(i);
            // Bodies and obstacles are contact groups, named in friction parameters: names are unique.
            for (const BodySpec& body : scene.bodies)
                if (body.name == o.name)
                    (f.has("name") ? f["name"] : f).fail("obstacle name '" + o.name + "' is already a body's name");
            for (const ObstacleSpec& other : scene.obstacles)
                if (other.name == o.name)
                    (f.has("name") ? f["name"] : f).fail("duplicate obstacle name '" + o.name + "'");
            const int group = int(scene.bodies.size() + i);
            Mesh mesh;
            JsonField g = f.has("plane") ? f["plane"] : f["mesh"];
            if (f.has("plane")) {
                g.require_object({ "point", "normal", "motion" });
                o.type = ObstacleType::PLANE;
                mesh.dim = dim;
                mesh.rest_positions = g["point"].vector(dim).transpose();
                const VectorXd n = g["normal"].vector(dim);
                if (!(n.stableNorm() > 0))
                    g["normal"].fail("must be a non-zero vector");
                o.normal = n.stableNormalized();
                mesh.elements.resize(0, dim + 1);
                mesh.boundary_facets.resize(0, dim);
                mesh.vertex_body = VectorXi::Zero(1);
                mesh.element_body.resize(0);
                mesh.facet_body.resize(0);
            } else {
                g.require_object({ "file", "translation", "scale", "motion" });
                o.type = ObstacleType::MESH;
                fs::path p(g["file"].string());
                if (p.is_relative())
                    p = fs::path(base_directory) / p;
                if (std::error_code ec; !fs::is_regular_file(p, ec))
                    g["file"].fail("cannot open obstacle mesh file '" + p.string() + "'"
                        + (ec ? " (" + ec.message() + ")" : std::string()));
                o.file = p.string();
                mesh = read_surface_mesh(o.file, dim);
                if (g.has("scale"))
                    mesh.rest_positions *= g["scale"].positive();
                if (g.has("translation")) {
                    const MatrixXd unplaced = mesh.rest_positions;
                    mesh.rest_positions.rowwise() += g["translation"].vector(dim).transpose();
                    check_placed_coordinates(mesh.rest_positions, f);
                    check_placement_keeps_cells(unplaced, mesh.rest_positions, mesh.boundary_facets, f);
                }
            }
            if (g.has("motion")) {
                for (auto& c : parse_components(g["motion"], dim, false))
                    o.motion.push_back(std::move(*c));
            } else {
                for (int a = 0; a < dim; ++a)
                    o.motion.emplace_back(0.0);
            }
            check_placed_coordinates(mesh.rest_positions, f);
            o.first_vertex = scene.mesh.num_vertices();
            o.num_vertices = mesh.num_vertices();
            append_mesh(scene.mesh, mesh, group);
            scene.obstacles.push_back(std::move(o));
        }
        if (!scene.obstacles.empty() && !scene.contact.enabled && !root.has("contact"))
            scene.contact.enabled = true; // obstacles imply contact unless it is switched off explicitly
    }

    /// The document's keys; "description" is free text, only checked to be a string.
    void check_top_level(const JsonField& root)
    {
        root.require_object({ "dimension", "bodies", "gravity", "dirichlet", "neumann", "time", "mass", "solver",
            "output", "description", "contact", "obstacles", "friction", "periodic", "device" });
        if (root.has("description"))
            root["description"].string();
    }

    int parse_dimension(const JsonField& f)
    {
        const int dim = f.integer(2);
        if (dim != 2 && dim != 3)
            f.fail("must be 2 or 3");
        return dim;
    }

    /// A body's "scale", "rotation" and `translation` applied to its mesh, in that order, each
    /// about the mesh's origin; refuses a placement that round-off would spoil.
    void place_body_mesh(const JsonField& bf, const VectorXd& translation, int dim, Mesh& mesh)
    {
        if (bf.has("scale")) {
            // The mesh file's units to metres, about the mesh's origin (before rotation and translation).
            mesh.rest_positions *= bf["scale"].positive();
            validate_mesh(mesh, bf["scale"].path());
        }
        const MatrixXd unplaced = mesh.rest_positions;
        if (bf.has("rotation")) {
            // Degrees; 2D: one angle; 3D: about x, then y, then z (R = Rz Ry Rx), about the mesh origin.
            const VectorXd angles = bf["rotation"].vector(dim == 2 ? 1 : 3) * (M_PI / 180.0);
            Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
            if (dim == 2)
                R = Eigen::AngleAxisd(angles[0], Eigen::Vector3d::UnitZ()).toRotationMatrix();
            else
                R = (Eigen::AngleAxisd(angles[2], Eigen::Vector3d::UnitZ())
                    * Eigen::AngleAxisd(angles[1], Eigen::Vector3d::UnitY())
                    * Eigen::AngleAxisd(angles[0], Eigen::Vector3d::UnitX()))
                        .toRotationMatrix();
            const Eigen::MatrixXd Rd = R.topLeftCorner(dim, dim);
            mesh.rest_positions = (mesh.rest_positions * Rd.transpose()).eval();
        }
        mesh.rest_positions.rowwise() += translation.transpose();
        check_placed_coordinates(mesh.rest_positions, bf);
        check_placement_keeps_cells(unplaced, mesh.rest_positions, mesh.elements, bf);
    }

    /// bodies[b]: appends its placed mesh (contact group b) and its BodySpec to `scene`.
    /// @return its "self_contact" if given: the default comes from the "contact" block, which
    /// is read after the bodies (its default dhat depends on their extent).
    std::optional<bool> parse_body(const JsonField& bf, size_t b, const std::string& base_directory, Scene& scene)
    {
        const int dim = scene.dim;
        bf.require_object({ "name", "mesh", "material", "initial_velocity", "scale", "translation", "rotation",
            "self_contact", "friction" });
        BodySpec body;
        body.name = bf.has("name") ? bf["name"].string() : "body" + std::to_string(b);
        for (const auto& other : scene.bodies)
            if (other.name == body.name)
                bf["name"].fail("duplicate body name '" + body.name + "'");
        body.material = parse_material(bf["material"], dim);
        body.initial_velocity = bf.has("initial_velocity") ? bf["initial_velocity"].vector(dim) : VectorXd::Zero(dim);
        body.translation = bf.has("translation") ? bf["translation"].vector(dim) : VectorXd::Zero(dim);
        if (bf.has("friction"))
            body.friction_coefficient = parse_local_friction(bf["friction"]);
        const std::optional<bool> self_contact
            = bf.has("self_contact") ? std::optional<bool>(bf["self_contact"].boolean()) : std::nullopt;
        Mesh mesh = parse_mesh(bf["mesh"], dim, base_directory, body.mesh_source, double(scene.mesh.num_elements()));
        place_body_mesh(bf, body.translation, dim, mesh);
        append_mesh(scene.mesh, mesh, int(b));
        scene.bodies.push_back(std::move(body));
        return self_contact;
    }

    /// "bodies": fills scene.bodies, the bodies' part of scene.mesh and scene.body_vertices.
    /// @return each body's "self_contact", if given (see parse_body).
    std::vector<std::optional<bool>> parse_bodies(
        const JsonField& list, const std::string& base_directory, Scene& scene)
    {
        list.require_array(1);
        std::vector<std::optional<bool>> self_contact_fields;
        scene.mesh.dim = scene.dim;
        for (size_t b = 0; b < list.size(); ++b)
            self_contact_fields.push_back(parse_body(list.at(b), b, base_directory, scene));
        scene.body_vertices = scene.mesh.num_vertices();
        return self_contact_fields;
    }

    /// A body without its own "self_contact" takes the "contact" block's.
    void set_self_contact(const std::vector<std::optional<bool>>& self_contact_fields, Scene& scene)
    {
        for (size_t b = 0; b < scene.bodies.size(); ++b)
            scene.bodies[b].self_contact = self_contact_fields[b].value_or(scene.contact.self_contact);
    }

    /// Tolerance of the Dirichlet and Neumann region tests: 1e-9 of the extent of the bodies
    /// (obstacles left out).
    double region_tolerance(const Scene& scene)
    {
        const auto body_rows = scene.mesh.rest_positions.topRows(scene.body_vertices);
        const Eigen::RowVectorXd extent = body_rows.colwise().maxCoeff() - body_rows.colwise().minCoeff();
        return 1e-9 * extent.norm();
    }

    void parse_dirichlet(const JsonField& root, double tolerance, Scene& scene)
    {
        if (!root.has("dirichlet"))
            return;
        const int dim = scene.dim;
        const JsonField list = root["dirichlet"];
        list.require_array();
        for (size_t i = 0; i < list.size(); ++i) {
            const JsonField f = list.at(i);
            f.require_object({ "body", "region", "displacement" });
            DirichletSpec d;
            d.field = f.path();
            d.body = parse_body_reference(f["body"], scene.bodies);
            d.region = parse_region(f["region"], dim);
            const JsonField disp = f["displacement"];
            d.displacement = parse_components(disp, dim, true);
            bool any = false;
            for (const auto& c : d.displacement)
                any = any || c.has_value();
            if (!any)
                disp.fail("all components are null: nothing is prescribed");
            bool selected = false;
            for (Index v = 0; v < scene.mesh.num_vertices() && !selected; ++v)
                selected = scene.mesh.vertex_body[v] == d.body
                    && d.region.contains(scene.mesh.rest_positions.row(v).transpose(), tolerance);
            if (!selected)
                f["region"].fail("selects no vertex of body '" + scene.bodies[size_t(d.body)].name + "'");
            scene.dirichlet.push_back(std::move(d));
        }
    }

    void parse_neumann(const JsonField& root, double tolerance, Scene& scene)
    {
        if (!root.has("neumann"))
            return;
        const int dim = scene.dim;
        const JsonField list = root["neumann"];
        list.require_array();
        for (size_t i = 0; i < list.size(); ++i) {
            const JsonField f = list.at(i);
            f.require_object({ "body", "region", "traction" });
            NeumannSpec n;
            n.field = f.path();
            n.body = parse_body_reference(f["body"], scene.bodies);
            n.region = parse_region(f["region"], dim);
            for (auto& c : parse_components(f["traction"], dim, false))
                n.traction.push_back(std::move(*c));
            bool selected = false;
            for (Index fc = 0; fc < scene.mesh.boundary_facets.rows() && !selected; ++fc) {
                if (scene.mesh.facet_body[fc] != n.body)
                    continue;
                bool inside = true;
                for (int a = 0; a < dim; ++a)
                    inside = inside
                        && n.region.contains(
                            scene.mesh.rest_positions.row(scene.mesh.boundary_facets(fc, a)).transpose(), tolerance);
                selected = inside;
            }
            if (!selected)
                f["region"].fail("selects no boundary facet of body '" + scene.bodies[size_t(n.body)].name + "'");
            scene.neumann.push_back(std::move(n));
        }
    }

    IntegratorType parse_integrator(const JsonField& f)
    {
        const std::string name = f.string();
        if (name == "static")
            return IntegratorType::STATIC;
        if (name == "implicit_euler")
            return IntegratorType::IMPLICIT_EULER;
        if (name == "bdf2")
            return IntegratorType::BDF2;
        if (name == "newmark")
            return IntegratorType::NEWMARK;
        f.fail("unknown integrator '" + name + "' (expected static, implicit_euler, bdf2 or newmark)");
    }

    void parse_time(const JsonField& time, Scene& scene)
    {
        time.require_object({ "integrator", "dt", "steps", "adaptive" });
        scene.time.integrator = parse_integrator(time["integrator"]);
        scene.time.dt = time["dt"].positive();
        if (scene.time.dt < MIN_TIME_STEP)
            time["dt"].fail(
                "time step below 1e-12 s: the implicit schemes weight the elastic forces by dt^2, which then "
                "vanish in round-off against inertia");
        scene.time.steps = time["steps"].integer(1);
        if (time.has("adaptive"))
            scene.time.adaptive = parse_adaptive(time["adaptive"], scene.time);
    }

    void parse_mass(const JsonField& root, Scene& scene)
    {
        if (!root.has("mass"))
            return;
        const std::string m = root["mass"].string();
        if (m == "lumped")
            scene.mass = MassType::LUMPED;
        else if (m == "consistent")
            scene.mass = MassType::CONSISTENT;
        else
            root["mass"].fail("expected \"lumped\" or \"consistent\"");
    }

    void parse_solver(const JsonField& root, Scene& scene)
    {
        if (!root.has("solver"))
            return;
        const JsonField s = root["solver"];
        s.require_object(
            { "residual_tolerance", "step_tolerance", "max_iterations", "linear_solver", "line_search_max_halvings",
                "armijo", "hessian_projection", "step_extension", "threads", "gpu_adjoint_preconditioner" });
        SolverSpec& solver = scene.solver;
        if (s.has("threads"))
            solver.threads = s["threads"].integer(1);
        if (s.has("hessian_projection")) {
            const std::string h = s["hessian_projection"].string();
            if (h != "adaptive" && h != "always")
                s["hessian_projection"].fail("expected \"adaptive\" or \"always\"");
            solver.adaptive_projection = h == "adaptive";
        }
        if (s.has("step_extension"))
            solver.step_extension = s["step_extension"].boolean();
        if (s.has("residual_tolerance"))
            solver.residual_tolerance = s["residual_tolerance"].positive();
        if (s.has("step_tolerance")) {
            solver.step_tolerance = s["step_tolerance"].number();
            if (solver.step_tolerance < 0)
                s["step_tolerance"].fail("must be >= 0 (0 disables the step criterion)");
        }
        if (s.has("max_iterations"))
            solver.max_iterations = s["max_iterations"].integer(1);
        if (s.has("line_search_max_halvings"))
            solver.line_search_max_halvings = s["line_search_max_halvings"].integer(1);
        if (s.has("armijo")) {
            solver.armijo = s["armijo"].number();
            if (!(solver.armijo > 0 && solver.armijo < 0.5))
                s["armijo"].fail("must lie in (0, 0.5)");
        }
        if (s.has("linear_solver")) {
            const std::string l = s["linear_solver"].string();
            if (l == "cholmod")
                solver.linear_solver = LinearSolverType::CHOLMOD;
            else if (l == "ldlt")
                solver.linear_solver = LinearSolverType::LDLT;
            else
                s["linear_solver"].fail("expected \"cholmod\" or \"ldlt\"");
        }
        if (s.has("gpu_adjoint_preconditioner")) {
            const std::string p = s["gpu_adjoint_preconditioner"].string();
            if (p != "multigrid" && p != "block_jacobi")
                s["gpu_adjoint_preconditioner"].fail("expected \"block_jacobi\" or \"multigrid\"");
            solver.gpu_adjoint_multigrid = p == "multigrid";
        }
    }

    void parse_output(const JsonField& root, Scene& scene)
    {
        if (!root.has("output"))
            return;
        const JsonField o = root["output"];
        o.require_object({ "directory", "vtu_every", "vtu_encoding", "hdf5", "flush_interval" });
        OutputSpec& output = scene.output;
        if (o.has("directory")) {
            output.directory = o["directory"].string();
            if (output.directory.empty())
                o["directory"].fail("an empty path (give a directory, e.g. \"output\", or leave the key out)");
        }
        if (o.has("vtu_every"))
            output.vtu_every = o["vtu_every"].integer(0);
        if (o.has("hdf5"))
            output.hdf5 = o["hdf5"].boolean();
        if (o.has("flush_interval"))
            output.flush_interval = o["flush_interval"].positive();
        if (o.has("vtu_encoding")) {
            const std::string encoding = o["vtu_encoding"].string();
            if (encoding == "binary")
                output.vtu_encoding = VtuEncoding::BINARY;
            else if (encoding == "ascii")
                output.vtu_encoding = VtuEncoding::ASCII;
            else
                o["vtu_encoding"].fail("expected \"binary\" or \"ascii\", got \"" + encoding + "\"");
        }
    }

} // namespace

void select_device(Scene& scene, const std::string& name, const std::string& field)
{
    if (name == "cpu") {
        scene.device = DeviceType::CPU;
        return;
    }
    if (name != "gpu")
        throw InputError(field, "expected \"cpu\" or \"gpu\", got \"" + name + "\"");
    const auto refuse = [&](const std::string& what) {
        throw InputError(field,
            "\"gpu\" does not support " + what
                + " yet (issue 17: the GPU path has elasticity, inertia (lumped or consistent mass), gravity, "
                  "tractions, Dirichlet "
                  "conditions, barrier and penalty contact with obstacles and lagged friction, automatic load stepping "
                  "and adaptive time stepping, periodic cells with contact across the boundary); use \"cpu\"");
    };
    // The effective coefficients, as Simulator::setup_friction takes them (< 0: the global one).
    bool friction = false;
    const auto effective = [&](double own) { return own >= 0 ? own : scene.friction.coefficient; };
    for (const BodySpec& b : scene.bodies)
        friction = friction || effective(b.friction_coefficient) > 0;
    for (const ObstacleSpec& o : scene.obstacles)
        friction = friction || effective(o.friction_coefficient) > 0;
    if (scene.periodic.enabled && scene.contact.enabled && friction)
        refuse("friction across a periodic cell's boundary");
    scene.device = DeviceType::GPU;
}

Scene parse_scene(const nlohmann::json& document, const std::string& base_directory, const std::string& source)
{
    Scene scene;
    scene.source = source;
    const JsonField root(document, "");
    check_top_level(root);
    scene.dim = parse_dimension(root["dimension"]);
    const std::vector<std::optional<bool>> self_contact_fields = parse_bodies(root["bodies"], base_directory, scene);
    parse_contact(root, scene);
    set_self_contact(self_contact_fields, scene);
    parse_obstacles(root, base_directory, scene);
    parse_friction(root, scene);
    scene.gravity = root.has("gravity") ? root["gravity"].vector(scene.dim) : VectorXd::Zero(scene.dim);
    const double tolerance = region_tolerance(scene);
    parse_dirichlet(root, tolerance, scene);
    parse_neumann(root, tolerance, scene);
    parse_time(root["time"], scene);
    parse_mass(root, scene);
    parse_solver(root, scene);
    parse_output(root, scene);
    if (root.has("periodic"))
        parse_periodic(root["periodic"], scene);
    if (root.has("device"))
        select_device(scene, root["device"].string(), "device");
    return scene;
}

Scene parse_scene_text(const std::string& text, const std::string& base_directory, const std::string& source)
{
    const nlohmann::json document = parse_json_text(text, source);
    return parse_scene(document, base_directory, source);
}

Scene load_scene(const std::string& path)
{
    return load_scene(parse_json_text(read_input_file(path, "scene file"), path), path);
}

Scene load_scene(const nlohmann::json& document, const std::string& path)
{
    const std::string base = fs::path(path).parent_path().string();
    try {
        return parse_scene(document, base.empty() ? "." : base, path);
    } catch (const InputError& e) {
        if (e.field() == path)
            throw;
        throw InputError(path + ": " + e.field(), e.message());
    }
}

} // namespace diffipc
