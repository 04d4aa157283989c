#pragma once
// Helpers shared by the forward tests: small scenes built as JSON in code.

#include "forward/scene/scene.hpp"
#include "forward/simulation/simulator.hpp"

#include <nlohmann/json.hpp>

#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace diffipc::test {

/// A single box body scene with no loads; tests add what they need.
inline nlohmann::json box_scene(int dim, std::vector<double> max, std::vector<int> cells,
    const std::string& model = "neo_hookean", double E = 1e5, double nu = 0.3, double density = 1000)
{
    nlohmann::json s;
    s["dimension"] = dim;
    std::vector<double> lo(static_cast<size_t>(dim), 0.0);
    s["bodies"]
        = { { { "name", "body" }, { "mesh", { { "box", { { "min", lo }, { "max", max }, { "cells", cells } } } } },
            { "material", { { "model", model }, { "E", E }, { "nu", nu }, { "density", density } } } } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", 1 } };
    s["solver"] = { { "residual_tolerance", 1e-10 } };
    return s;
}

/// A neo-Hookean box body (E = 1e5, nu = 0.3, density 1000) for contact scenes.
inline nlohmann::json box_body(
    const std::string& name, std::vector<double> lo, std::vector<double> hi, std::vector<int> cells)
{
    return { { "name", name }, { "mesh", { { "box", { { "min", lo }, { "max", hi }, { "cells", cells } } } } },
        { "material", { { "model", "neo_hookean" }, { "E", 1e5 }, { "nu", 0.3 }, { "density", 1000 } } } };
}

inline nlohmann::json region(std::vector<double> lo, std::vector<double> hi)
{
    return { { "min", lo }, { "max", hi } };
}

/// A neo-Hookean periodic cell [0, 1] x [0, 0.8] (x [0, 1]) compressed by G_xx = -0.2 t, its
/// lateral diagonal components free, under gravity, over 3 steps of 0.05 s (scene "periodic").
inline nlohmann::json compressed_periodic_cell(int dim, const std::string& integrator)
{
    using json = nlohmann::json;
    json s = dim == 2 ? box_scene(2, { 1, 0.8 }, { 4, 3 }, "neo_hookean", 1e5, 0.3, 1000)
                      : box_scene(3, { 1, 0.8, 1 }, { 2, 2, 2 }, "neo_hookean", 1e5, 0.3, 1000);
    s["periodic"] = { { "gradient",
        dim == 2 ? json { { "-0.2*t", 0 }, { 0, nullptr } }
                 : json { { "-0.2*t", 0, 0 }, { 0, nullptr, 0 }, { 0, 0, nullptr } } } };
    s["gravity"] = dim == 2 ? json { 0, -50 } : json { 0, -50, 0 };
    s["time"] = { { "integrator", integrator }, { "dt", 0.05 }, { "steps", 3 } };
    s["solver"] = { { "residual_tolerance", 1e-11 } };
    return s;
}

/// A shallow arch: the top of a thin ring (radius 1 m, 5 mm thick) between |x| = 0.31 m, clamped
/// where the ring is fixed below y = 0.95, pressed at its apex by a traction ramped to 300 Pa over
/// 20 steps. It snaps through between t = 0.1 and 0.15 s: the apex jumps from 0.985 m to 0.916 m
/// (a limit point of the load), which no load increment, however small, avoids.
inline nlohmann::json shallow_arch(int steps, int max_iterations, const nlohmann::json& adaptive)
{
    nlohmann::json s = { { "dimension", 2 },
        { "bodies",
            { { { "name", "ring" },
                { "mesh",
                    { { "annulus",
                        { { "inner_radius", 0.995 }, { "outer_radius", 1.0 }, { "segments", 480 },
                            { "layers", 1 } } } } },
                { "material", { { "model", "neo_hookean" }, { "E", 1e6 }, { "nu", 0.3 }, { "density", 1000 } } } } } },
        { "dirichlet",
            { { { "body", 0 }, { "region", region({ -2, -2 }, { 2, 0.95 }) },
                { "displacement", { 0, 0 } } } } },
        { "neumann",
            { { { "body", 0 }, { "region", region({ -0.05, 0.99 }, { 0.05, 1.1 }) },
                { "traction", { 0, "-300*t" } } } } },
        { "contact", { { "dhat", 1e-3 }, { "kappa", 1e5 } } },
        { "time", { { "integrator", "static" }, { "dt", 0.05 }, { "steps", steps } } },
        { "solver", { { "max_iterations", max_iterations } } } };
    if (!adaptive.is_null())
        s["time"]["adaptive"] = adaptive;
    return s;
}

/// The bytes of a file ("" if it cannot be read).
inline std::string read_file(const std::string& path)
{
    std::ifstream in(path, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

inline Scene make_scene(const nlohmann::json& j) { return parse_scene(j, ".", "<test>"); }

/// Random vector with entries in [-1, 1], fixed seed per call site.
inline Eigen::VectorXd random_vector(Eigen::Index n, unsigned seed)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    Eigen::VectorXd v(n);
    for (Eigen::Index i = 0; i < n; ++i)
        v[i] = u(rng);
    return v;
}

} // namespace diffipc::test
