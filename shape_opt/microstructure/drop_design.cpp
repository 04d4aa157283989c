#include "shape_opt/microstructure/drop_design.hpp"

#include "adjoint/adjoint.hpp"
#include "forward/common/error.hpp"
#include "forward/common/timer.hpp"
#include "forward/mesh/gmsh_writer.hpp"
#include "forward/scene/json_field.hpp"
#include "forward/scene/scene.hpp"
#include "forward/simulation/simulator.hpp"
#include "objectives/body_force.hpp"
#include "shape_opt/microstructure/cell_tiling.hpp"

namespace diffipc {

namespace {
    constexpr double gravity = 9.81;
}

DropSettings parse_drop_settings(const JsonField& f)
{
    f.require_object({ "height", "size", "cells", "material", "block", "dhat", "kappa", "friction", "dt", "steps",
        "max_p", "target_stress", "solver" });
    DropSettings s;
    if (f.has("height"))
        s.mesh.height = f["height"].positive();
    s.mesh.size = f.has("size") ? f["size"].positive() : s.mesh.height / 40;
    if (f.has("cells")) {
        const VectorXi n = f["cells"].int_vector(2, 1);
        s.nx = n[0];
        s.ny = n[1];
    }
    if (f.has("material")) {
        f["material"].require_object({ "model", "E", "nu", "density", "plane" });
        s.material = f["material"].json();
    }
    const JsonField block = f["block"];
    block.require_object({ "E", "mass", "speed", "gap" });
    if (block.has("E"))
        s.block_E = block["E"].positive();
    s.mass = block["mass"].positive();
    if (block.has("speed"))
        s.speed = block["speed"].number();
    if (block.has("gap"))
        s.gap = block["gap"].positive();
    if (f.has("dhat"))
        s.dhat = f["dhat"].positive();
    s.kappa = f["kappa"].positive();
    if (f.has("friction")) {
        s.friction = f["friction"].number();
        if (s.friction < 0)
            f["friction"].fail("expected a friction coefficient >= 0");
    }
    if (f.has("dt"))
        s.dt = f["dt"].positive();
    if (f.has("steps"))
        s.steps = f["steps"].integer(1);
    if (f.has("max_p")) {
        s.max_p = f["max_p"].number();
        if (!(s.max_p >= 1))
            f["max_p"].fail("expected an exponent >= 1");
    }
    s.target_stress = f["target_stress"].positive();
    if (f.has("solver"))
        s.solver = f["solver"].json();
    return s;
}

DropDesign::DropDesign(CellFamily family, DropSettings settings)
    : m_family(std::move(family))
    , m_settings(std::move(settings))
{
    const DropSettings& s = m_settings;
    if (!(s.target_stress > 0))
        throw InputError("target_stress", "the plateau's target stress must be positive");
    if (!(s.mass > 0))
        throw InputError("block.mass", "the block's mass per depth must be positive");
    if (!(s.kappa > 0))
        throw InputError("kappa", "a fixed barrier stiffness (> 0) is needed to differentiate the drop");
    if (s.nx < 1 || s.ny < 1)
        throw InputError("cells", "expected at least one cell along each axis");
}

nlohmann::json DropDesign::scene(const std::string& pad_file, double width) const
{
    using json = nlohmann::json;
    const DropSettings& s = m_settings;
    const double h = s.mesh.height, W = s.nx * width * h, top = s.ny * h;
    const double gap = s.gap > 0 ? s.gap : h / 20;
    json scene;
    scene["dimension"] = 2;
    const json block_box
        = { { "min", { 0.0, top + gap } }, { "max", { W, top + gap + h } }, { "cells", { 4 * s.nx, 4 } } };
    scene["bodies"] = { { { "name", "pad" }, { "mesh", { { "file", pad_file } } }, { "material", s.material } },
        { { "name", "block" }, { "mesh", { { "box", block_box } } },
            { "material",
                { { "model", "neo_hookean" }, { "E", s.block_E }, { "nu", 0.3 }, { "density", s.mass / (W * h) },
                    { "plane", "stress" } } },
            { "initial_velocity", { 0.0, -s.speed } } } };
    scene["gravity"] = { 0.0, -gravity };
    scene["dirichlet"]
        = { { { "body", 0 }, { "region", { { "min", { -W, -1e-9 * h } }, { "max", { 2 * W, 1e-9 * h } } } },
            { "displacement", { 0, 0 } } } };
    scene["contact"] = { { "dhat", s.dhat > 0 ? s.dhat : h / 1000 }, { "kappa", s.kappa } };
    if (s.friction > 0)
        scene["friction"] = { { "coefficient", s.friction } };
    scene["time"] = { { "integrator", "implicit_euler" }, { "dt", s.dt }, { "steps", s.steps } };
    scene["solver"] = s.solver;
    return scene;
}

std::string DropDesign::write_scene(const VectorXd& p, const std::string& directory) const
{
    const double width = p[m_family.width_index()];
    const CellTiling pad(
        mesh_design(m_family, p, m_settings.mesh), width, m_settings.mesh.height, m_settings.nx, m_settings.ny);
    nlohmann::json j = scene("pad.msh", width);
    j["description"] = "A block dropped on a pad of microstructure cells (diffipc.microstructure / DropDesign)";
    return write_mesh_and_scene(directory, "pad.msh", pad.mesh(), j);
}

DropEvaluation DropDesign::evaluate(const VectorXd& p, bool gradient) const
{
    const DesignMesh m = mesh_with_velocity(*this, p, gradient);
    return evaluate_mesh(m.mesh, p, m.velocity_or_null());
}

DesignValue DropDesign::value(const Mesh& cell, const VectorXd& p, const MatrixXd* velocity) const
{
    return evaluate_mesh(cell, p, velocity);
}

DropEvaluation DropDesign::evaluate_mesh(const Mesh& cell, const VectorXd& p, const MatrixXd* velocity) const
{
    const Timer timer;
    const DropSettings& s = m_settings;
    const double width = p[m_family.width_index()];
    const CellTiling pad(cell, width, s.mesh.height, s.nx, s.ny);
    const TemporaryGmshFile file(pad.mesh());
    Simulator sim(parse_scene(scene(file.path(), width), "", "drop design"));
    const Trajectory& trajectory = sim.run();
    DropEvaluation out;
    out.width = s.nx * width * s.mesh.height;
    out.vertices = sim.mesh().num_vertices();
    out.elements = sim.mesh().num_elements();
    out.newton_iterations = trajectory.newton_iterations;
    if (trajectory.final_status != StepStatus::CONVERGED) {
        out.message = "the drop failed at step " + std::to_string(trajectory.committed() + 1) + ": "
            + trajectory.failure_message;
        out.seconds = timer.seconds();
        return out;
    }
    const BodyForce force(1, 1, TimeMode::MAX_P, s.max_p);
    const VectorXd F = force.forces(sim, trajectory);
    out.time.resize(s.steps);
    for (int k = 1; k <= s.steps; ++k)
        out.time[k - 1] = trajectory.steps[size_t(k - 1)].time;
    out.stress = F / out.width;
    out.deceleration = F / s.mass - VectorXd::Constant(F.size(), gravity);
    out.peak = out.stress.maxCoeff();
    const double scale = 1 / (out.width * s.target_stress);
    out.J = scale * force.value(sim, trajectory);
    if (velocity) {
        ParameterRequest request;
        request.rest_positions = true;
        request.density = true;
        StateSeed seed;
        seed.resize(s.steps);
        force.add_gradient(sim, trajectory, request, scale, seed);
        const ParameterGradient g = adjoint_gradient(sim, seed, request);
        const Mesh& mesh = sim.mesh();
        const Index pad_dofs = 2 * pad.mesh().num_vertices();
        for (Index v = 0; v < mesh.num_vertices(); ++v)
            if ((mesh.vertex_body[v] == 0) != (2 * v < pad_dofs))
                throw std::logic_error("drop design: the scene's vertices are not the pad's, then the block's");
        out.gradient = velocity->transpose() * pad.pullback(g.rest_positions.head(pad_dofs));
        // The width: every vertex stretches along x, the block's density falls, W grows.
        double dw = 0;
        for (Index v = 0; v < mesh.num_vertices(); ++v)
            dw += g.rest_positions[2 * v] * mesh.rest_positions(v, 0) / width;
        const double rho = s.mass / (out.width * s.mesh.height);
        if (g.density.size())
            for (Index e = 0; e < mesh.num_elements(); ++e)
                if (mesh.element_body[e] == 1)
                    dw -= g.density[e] * rho / width;
        out.gradient[m_family.width_index()] = dw - out.J / width;
    }
    out.ok = true;
    out.seconds = timer.seconds();
    return out;
}

} // namespace diffipc
