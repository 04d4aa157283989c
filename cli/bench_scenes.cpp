#include "cli/bench_scenes.hpp"

namespace diffipc {

nlohmann::json beam(int dim, const std::string& model, std::vector<int> cells, std::vector<double> extent, int steps,
    double E, double dt)
{
    nlohmann::json s;
    s["dimension"] = dim;
    std::vector<double> lo(size_t(dim), 0.0);
    s["bodies"]
        = { { { "name", "beam" }, { "mesh", { { "box", { { "min", lo }, { "max", extent }, { "cells", cells } } } } },
            { "material", { { "model", model }, { "E", E }, { "nu", 0.3 }, { "density", 1000 } } } } };
    std::vector<double> g(size_t(dim), 0.0);
    g[1] = -9.81;
    s["gravity"] = g;
    std::vector<double> rmin(size_t(dim), -1.0), rmax(size_t(dim), 10.0);
    rmin[0] = -1e-9;
    rmax[0] = 1e-9;
    std::vector<nlohmann::json> zero(size_t(dim), 0);
    s["dirichlet"]
        = { { { "body", "beam" }, { "region", { { "min", rmin }, { "max", rmax } } }, { "displacement", zero } } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", dt }, { "steps", steps } };
    s["solver"] = { { "residual_tolerance", 1e-6 } };
    return s;
}

/// A ~20k-tet contact scene: a soft slab dropped on a clamped one.
nlohmann::json contact_slabs(bool full, int steps, double friction)
{
    // full: 24 x 3 x 24 and 20 x 4 x 20 cubes, 6 tets each: 10,368 + 9,600 = 19,968 tetrahedra.
    return full ? contact_slabs({ 24, 3, 24 }, { 20, 4, 20 }, steps, friction)
                : contact_slabs({ 8, 2, 8 }, { 6, 2, 6 }, steps, friction);
}

nlohmann::json contact_slabs(std::vector<int> base_cells, std::vector<int> slab_cells, int steps, double friction)
{
    auto slab = [](const std::string& name, std::vector<double> lo, std::vector<double> hi, std::vector<int> cells,
                    std::vector<double> v) {
        return nlohmann::json { { "name", name },
            { "mesh", { { "box", { { "min", lo }, { "max", hi }, { "cells", cells } } } } },
            { "material", { { "model", "neo_hookean" }, { "E", 1e6 }, { "nu", 0.3 }, { "density", 1000 } } },
            { "initial_velocity", v }, { "self_contact", false } };
    };
    nlohmann::json s;
    s["dimension"] = 3;
    s["bodies"] = { slab("base", { -0.6, -0.15, -0.6 }, { 0.6, 0.0, 0.6 }, base_cells, { 0, 0, 0 }),
        slab("slab", { -0.5, 0.002, -0.5 }, { 0.5, 0.202, 0.5 }, slab_cells, { 0, -1, 0 }) };
    s["gravity"] = { 0, -9.81, 0 };
    s["dirichlet"] = { { { "body", "base" }, { "region", { { "min", { -1, -1, -1 } }, { "max", { 1, -0.15, 1 } } } },
        { "displacement", { 0, 0, 0 } } } };
    s["contact"] = { { "dhat", 1e-3 }, { "kappa", "adaptive" } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.005 }, { "steps", steps } };
    s["solver"] = { { "residual_tolerance", 1e-6 } };
    if (friction > 0)
        s["friction"] = { { "coefficient", friction } };
    return s;
}

} // namespace diffipc
