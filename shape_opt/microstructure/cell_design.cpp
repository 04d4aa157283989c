#include "shape_opt/microstructure/cell_design.hpp"

#include "adjoint/adjoint.hpp"
#include "forward/common/error.hpp"
#include "forward/common/timer.hpp"
#include "forward/mesh/gmsh_writer.hpp"
#include "forward/scene/json_field.hpp"
#include "forward/scene/scene.hpp"
#include "forward/simulation/simulator.hpp"
#include "objectives/combinators.hpp"
#include "objectives/macro_gradient.hpp"
#include "objectives/macro_stress.hpp"
#include "objectives/state_tracking.hpp"
#include "shape_opt/microstructure/cell_shape_map.hpp"

#include <algorithm>
#include <cmath>

namespace diffipc {

CellDesignSettings parse_cell_design_settings(const JsonField& f)
{
    f.require_object({ "height", "size", "material", "dhat", "kappa", "max_strain", "steps", "samples", "cap_samples",
        "target_stress", "shear_weight", "lateral_weight", "shear", "solver" });
    CellDesignSettings s;
    if (f.has("height"))
        s.mesh.height = f["height"].positive();
    s.mesh.size = f.has("size") ? f["size"].positive() : s.mesh.height / 40;
    if (f.has("material")) {
        f["material"].require_object({ "model", "E", "nu", "density", "plane" });
        s.material = f["material"].json();
    }
    if (f.has("dhat"))
        s.dhat = f["dhat"].positive();
    if (f.has("kappa"))
        s.kappa = f["kappa"].positive();
    if (f.has("max_strain")) {
        s.max_strain = f["max_strain"].positive();
        if (s.max_strain >= 0.9)
            f["max_strain"].fail("expected a compressive strain below 0.9");
    }
    if (f.has("steps"))
        s.steps = f["steps"].integer(1);
    if (f.has("samples")) {
        const JsonField a = f["samples"];
        a.require_array(1);
        s.samples.clear();
        for (size_t i = 0; i < a.size(); ++i)
            s.samples.push_back(a.at(i).integer(1));
    }
    if (f.has("cap_samples")) {
        const JsonField a = f["cap_samples"];
        a.require_array(0);
        for (size_t i = 0; i < a.size(); ++i)
            s.cap_samples.push_back(a.at(i).integer(1));
    }
    for (const auto& [key, steps] :
        { std::make_pair("samples", &s.samples), std::make_pair("cap_samples", &s.cap_samples) })
        for (size_t i = 0; i < steps->size(); ++i)
            if ((*steps)[i] > s.steps)
                throw InputError(f.path() + "." + key + "[" + std::to_string(i) + "]",
                    "step " + std::to_string((*steps)[i]) + " is beyond the " + std::to_string(s.steps) + " steps");
    s.target_stress = f["target_stress"].positive();
    if (f.has("shear_weight"))
        s.shear_weight = f["shear_weight"].number();
    if (f.has("lateral_weight"))
        s.lateral_weight = f["lateral_weight"].number();
    for (const char* key : { "shear_weight", "lateral_weight" })
        if (f.has(key) && f[key].number() < 0)
            f[key].fail("expected a weight >= 0");
    if (f.has("shear")) {
        const std::string shear = f["shear"].string();
        if (shear != "free" && shear != "fixed")
            f["shear"].fail("expected \"free\" or \"fixed\", got \"" + shear + "\"");
        s.free_shear = shear == "free";
    }
    if (f.has("solver"))
        s.solver = f["solver"].json();
    return s;
}

CellDesign::CellDesign(CellFamily family, CellDesignSettings settings)
    : m_family(std::move(family))
    , m_settings(std::move(settings))
{
    if (!(m_settings.target_stress > 0))
        throw InputError("target_stress", "the plateau's target stress must be positive");
}

nlohmann::json CellDesign::scene(const std::string& mesh_file, double width) const
{
    using json = nlohmann::json;
    const CellDesignSettings& s = m_settings;
    const double h = s.mesh.height;
    const Eigen::Vector2d lo = cell_box_min(width, h), hi = cell_box_max(width, h);
    const double E = s.material.value("E", 1e6);
    json scene;
    scene["dimension"] = 2;
    scene["bodies"] = { { { "name", "cell" }, { "mesh", { { "file", mesh_file } } }, { "material", s.material } } };
    const json shear = s.free_shear ? json(nullptr) : json(0);
    scene["periodic"] = { { "gradient", { { nullptr, shear }, { 0, format_number(-s.max_strain) + "*t" } } },
        { "box", { { "min", { lo.x(), lo.y() } }, { "max", { hi.x(), hi.y() } } } } };
    scene["contact"]
        = { { "dhat", s.dhat > 0 ? s.dhat : h / 1000 }, { "kappa", s.kappa > 0 ? s.kappa : 1e4 * E / (h * h) } };
    scene["time"] = { { "integrator", "static" }, { "dt", 1.0 / s.steps }, { "steps", s.steps } };
    scene["solver"] = s.solver;
    return scene;
}

std::string CellDesign::write_scene(const VectorXd& p, const std::string& directory) const
{
    nlohmann::json j = scene("cell.msh", p[m_family.width_index()]);
    j["description"] = "A microstructure cell's compression (diffipc.microstructure / CellDesign::write_scene)";
    return write_mesh_and_scene(directory, "cell.msh", mesh_design(m_family, p, m_settings.mesh), j);
}

CellEvaluation CellDesign::evaluate(const VectorXd& p, bool gradient) const
{
    const DesignMesh m = mesh_with_velocity(*this, p, gradient);
    return evaluate_mesh(m.mesh, p, m.velocity_or_null());
}

CellEvaluation CellDesign::evaluate_moved(
    const Mesh& reference, const VectorXd& p, const VectorXd& q, bool gradient) const
{
    const CellShapeMap map(m_family, p, reference, m_settings.mesh.height);
    Mesh mesh = reference;
    mesh.rest_positions = map.moved(q);
    if (!gradient)
        return evaluate_mesh(mesh, q, nullptr);
    const MatrixXd velocity = map.moved_jacobian(q);
    return evaluate_mesh(mesh, q, &velocity);
}

CellEvaluation CellDesign::evaluate_mesh(const Mesh& mesh, const VectorXd& p, const MatrixXd* velocity) const
{
    const bool gradient = velocity != nullptr;
    const Timer timer;
    const CellDesignSettings& s = m_settings;
    const double width = p[m_family.width_index()];
    CellEvaluation out;
    out.vertices = mesh.num_vertices();
    out.elements = mesh.num_elements();
    const TemporaryGmshFile file(mesh);
    Simulator sim(parse_scene(scene(file.path(), width), "", "cell design"));
    const Trajectory& trajectory = sim.run();
    out.newton_iterations = trajectory.newton_iterations;
    if (trajectory.final_status != StepStatus::CONVERGED) {
        out.message = "the compression failed at step " + std::to_string(trajectory.committed() + 1) + ": "
            + trajectory.failure_message;
        out.seconds = timer.seconds();
        return out;
    }
    const int T = s.steps;
    out.strain.resize(T);
    out.stress.resize(T);
    out.shear.resize(T);
    out.lateral.resize(T);
    out.contacts.resize(T);
    for (int k = 1; k <= T; ++k) {
        const StepRecord& r = trajectory.steps[size_t(k - 1)];
        out.strain[k - 1] = s.max_strain * k / T;
        out.stress[k - 1] = -r.macro_stress[3];
        out.shear[k - 1] = r.macro_gradient[1];
        out.lateral[k - 1] = r.macro_gradient[0];
        out.contacts[k - 1] = int(r.active_contacts);
    }
    // J as objectives: 1/2 w (f - y)^2 per sample with w = 2 / sigma*^2 (stress, target -sigma*),
    // 2 w_s (G_xy, target 0), 2 w_l (G_xx, target 0); at the cap samples only a compressive
    // stress above sigma* (P_yy below -sigma*) counts.
    const size_t n = s.samples.size();
    const double sigma = s.target_stress;
    std::vector<WeightedSum::Term> terms;
    terms.push_back({ 1.0,
        std::make_unique<StateTracking>(
            std::make_unique<MacroStress>(1, 1, 2), s.samples, std::vector<double>(n, -sigma), 2 / (sigma * sigma)) });
    if (!s.cap_samples.empty())
        terms.push_back({ 1.0,
            std::make_unique<StateTracking>(std::make_unique<MacroStress>(1, 1, 2), s.cap_samples,
                std::vector<double>(s.cap_samples.size(), -sigma), 2 / (sigma * sigma), TrackingSide::BELOW) });
    if (s.shear_weight > 0)
        terms.push_back({ 1.0,
            std::make_unique<StateTracking>(std::make_unique<MacroGradient>(0, 1, 2), s.samples,
                std::vector<double>(n, 0.0), 2 * s.shear_weight) });
    if (s.lateral_weight > 0)
        terms.push_back({ 1.0,
            std::make_unique<StateTracking>(std::make_unique<MacroGradient>(0, 0, 2), s.samples,
                std::vector<double>(n, 0.0), 2 * s.lateral_weight) });
    const WeightedSum J(std::move(terms));
    out.J = J.value(sim, trajectory);
    if (gradient) {
        ParameterRequest request;
        request.rest_positions = true;
        StateSeed seed;
        seed.resize(T);
        J.add_gradient(sim, trajectory, request, 1.0, seed);
        const ParameterGradient g = adjoint_gradient(sim, seed, request);
        out.gradient = velocity->transpose() * g.rest_positions;
        // The stress divides by |Y| = width height^2, fixed in the scene: d sigma-term / d width
        // = sum_i w (P_i - y_i) (-P_i / |Y|) d|Y|/d width = -sum_i w (P_i - y_i) P_i / width.
        double volume_term = 0;
        for (int k : s.samples) {
            const double P = trajectory.steps[size_t(k - 1)].macro_stress[3];
            volume_term -= 2 / (sigma * sigma) * (P + sigma) * P / width;
        }
        for (int k : s.cap_samples) {
            const double P = trajectory.steps[size_t(k - 1)].macro_stress[3];
            volume_term -= 2 / (sigma * sigma) * std::min(P + sigma, 0.0) * P / width;
        }
        out.gradient[m_family.width_index()] += volume_term;
    }
    out.ok = true;
    out.seconds = timer.seconds();
    return out;
}

DesignValue CellDesign::value(const Mesh& cell, const VectorXd& p, const MatrixXd* velocity) const
{
    return evaluate_mesh(cell, p, velocity);
}

} // namespace diffipc
