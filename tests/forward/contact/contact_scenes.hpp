#pragma once
// Contact test scenes shared by the barrier's and the penalty's derivative checks: states with
// active contacts of every kind (2D vertex-edge and vertex-plane; 3D vertex-face, edge-edge and
// vertex-plane).

#include "../test_utils.hpp"

#include "forward/simulation/simulator.hpp"

#include <cmath>

namespace diffipc::test {

/// Two 2D rings resting within 0.5 mm of a plane and of each other; `contact` is the scene's block.
inline nlohmann::json rings_on_plane(const nlohmann::json& contact)
{
    nlohmann::json s;
    s["dimension"] = 2;
    nlohmann::json ring = { { "mesh",
                                { { "annulus",
                                    { { "center", { 0, 0.3 } }, { "inner_radius", 0.2 }, { "outer_radius", 0.2995 },
                                        { "segments", 24 }, { "layers", 1 } } } } },
        { "material", { { "model", "neo_hookean" }, { "E", 1e5 }, { "nu", 0.3 }, { "density", 1000 } } } };
    nlohmann::json ring2 = ring;
    ring2["mesh"]["annulus"]["center"] = { 0.5995, 0.3 };
    ring["name"] = "a";
    ring2["name"] = "b";
    s["bodies"] = { ring, ring2 };
    s["obstacles"] = { { { "plane", { { "point", { 0, 0 } }, { "normal", { 0, 1 } } } } } };
    s["contact"] = contact;
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", 1 } };
    return s;
}

/// Two 3D boxes, the second on the first, both within 0.5 mm of each other and of a plane.
inline nlohmann::json boxes_on_plane(const nlohmann::json& contact)
{
    nlohmann::json s;
    s["dimension"] = 3;
    auto box = [](const std::string& name, std::vector<double> lo, std::vector<double> hi) {
        return box_body(name, lo, hi, std::vector<int> { 2, 1, 2 });
    };
    s["bodies"] = { box("a", { 0, 0.0005, 0 }, { 1, 0.5, 1 }), box("b", { 0.1, 0.5005, 0.1 }, { 0.9, 1.0, 0.9 }) };
    s["obstacles"] = { { { "plane", { { "point", { 0, 0, 0 } }, { "normal", { 0, 1, 0 } } } } } };
    s["contact"] = contact;
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", 1 } };
    return s;
}

/// A soft box falling onto a plane obstacle that rises at 0.2 m/s (prescribed obstacle dofs),
/// with gravity and contact (dhat 2e-3, kappa 1e3): it lands during the run.
inline nlohmann::json falling_box(int dim, const std::string& integrator, double dt, int steps)
{
    nlohmann::json s = dim == 2 ? box_scene(2, { 0.2, 0.1 }, { 4, 2 }, "neo_hookean", 2e4, 0.3, 1000)
                                : box_scene(3, { 0.2, 0.1, 0.2 }, { 2, 1, 2 }, "neo_hookean", 2e4, 0.3, 1000);
    s["gravity"] = dim == 2 ? nlohmann::json { 0, -9.81 } : nlohmann::json { 0, -9.81, 0 };
    s["bodies"][0]["translation"] = dim == 2 ? nlohmann::json { 0, 0.01 } : nlohmann::json { 0, 0.01, 0 };
    s["bodies"][0]["initial_velocity"] = dim == 2 ? nlohmann::json { 0.1, -0.5 } : nlohmann::json { 0.1, -0.5, -0.05 };
    nlohmann::json plane = { { "point", dim == 2 ? nlohmann::json { 0, 0 } : nlohmann::json { 0, 0, 0 } },
        { "normal", dim == 2 ? nlohmann::json { 0, 1 } : nlohmann::json { 0, 1, 0 } },
        { "motion", dim == 2 ? nlohmann::json { 0, "0.2*t" } : nlohmann::json { 0, "0.2*t", 0 } } };
    s["obstacles"] = { { { "name", "floor" }, { "plane", plane } } };
    s["contact"] = { { "dhat", 2e-3 }, { "kappa", 1e3 } };
    s["time"] = { { "integrator", integrator }, { "dt", dt }, { "steps", steps } };
    s["solver"] = { { "residual_tolerance", 1e-10 } };
    return s;
}

/// A neo-Hookean block (0.1 x 0.05 (x 0.1) m) resting 50 um above a horizontal plane, the incline
/// modelled by gravity tilted by `theta` (rad), with friction coefficient mu (eps_v 1e-3, 10 lagging
/// iterations), dhat 0.1 mm, implicit Euler with step dt, residual tolerance 1e-8.
inline nlohmann::json block_on_incline(int dim, double theta, double mu, double dt, int steps)
{
    const double g = 9.81;
    nlohmann::json s
        = box_scene(dim, dim == 2 ? std::vector<double> { 0.1, 0.05 } : std::vector<double> { 0.1, 0.05, 0.1 },
            dim == 2 ? std::vector<int> { 4, 2 } : std::vector<int> { 2, 1, 2 }, "neo_hookean", 1e7, 0.3, 1000);
    s["bodies"][0]["translation"] = dim == 2 ? nlohmann::json { 0, 5e-5 } : nlohmann::json { 0, 5e-5, 0 };
    std::vector<double> gravity(size_t(dim), 0.0), normal(size_t(dim), 0.0), origin(size_t(dim), 0.0);
    gravity[0] = g * std::sin(theta);
    gravity[1] = -g * std::cos(theta);
    normal[1] = 1;
    s["gravity"] = gravity;
    s["obstacles"] = { { { "plane", { { "point", origin }, { "normal", normal } } } } };
    s["contact"] = { { "dhat", 1e-4 } };
    s["friction"] = { { "coefficient", mu }, { "eps_v", 1e-3 }, { "iterations", 10 } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", dt }, { "steps", steps } };
    s["solver"] = { { "residual_tolerance", 1e-8 } };
    return s;
}

/// block_on_incline() in 2D on a 60 degree incline with mu = 2, eps_v = 1e-5 and a single lagging solve per
/// step (100 steps of 1 ms): some step's lagged data does not describe its solution.
inline nlohmann::json unconverged_lagging_scene()
{
    nlohmann::json s = block_on_incline(2, 60 * M_PI / 180, 2.0, 1e-3, 100);
    s["friction"]["eps_v"] = 1e-5;
    s["friction"]["iterations"] = 1;
    return s;
}

/// The committed steps of a run whose friction lagging did not converge.
inline int unconverged_lagging_steps(const Trajectory& trajectory)
{
    int count = 0;
    for (const StepRecord& r : trajectory.steps)
        count += !r.friction_converged;
    return count;
}

/// boxes_on_plane()'s positions with body b turned by `angle` (rad) about the vertical axis through
/// its centre, so that its edges cross body a's.
inline Eigen::VectorXd turn_upper_box(const Simulator& sim, double angle)
{
    Eigen::VectorXd x = sim.positions();
    for (Index v = 0; v < sim.scene().body_vertices; ++v) {
        if (sim.mesh().vertex_body[v] != 1)
            continue;
        const double px = x[v * 3] - 0.5, pz = x[v * 3 + 2] - 0.5;
        x[v * 3] = 0.5 + std::cos(angle) * px - std::sin(angle) * pz;
        x[v * 3 + 2] = 0.5 + std::sin(angle) * px + std::cos(angle) * pz;
    }
    return x;
}

} // namespace diffipc::test
