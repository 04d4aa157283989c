// Checkpointed adjoint (adjoint/checkpointing.hpp) against the full-memory one on a
// transient scene: forward, recomputation and adjoint times, their ratio to the
// forward, and the records held at the peak. Prints figures; asserts nothing except
// that both gradients agree (docs/performance.md "Checkpointed adjoint").
//
//   bench_checkpointing [beam|drop] [steps] [stride ...]
//
// beam: a 3D cantilever (20 x 4 x 4 cubes, 1,920 tets) released from rest under
// gravity, implicit Euler. drop: a 3D box (12 x 4 x 12 cubes, 3,456 tets) falling onto
// a plane with a fixed barrier stiffness, landing during the run.
// Strides: 0 is the default ceil(sqrt(h T)); without any, 0 alone.
// J = sum_k 1/2 |x_k - X|^2 / L^2 over every state, so every state is seeded (its explicit
// dependence on X is left out: the bench compares the sweeps, not J's partials).

#include "adjoint/checkpointing.hpp"
#include "forward/scene/scene.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

using namespace diffipc;
using json = nlohmann::json;

namespace {

json body(const std::vector<double>& lo, const std::vector<double>& hi, const std::vector<int>& cells, double E)
{
    return { { "name", "body" }, { "mesh", { { "box", { { "min", lo }, { "max", hi }, { "cells", cells } } } } },
        { "material", { { "model", "neo_hookean" }, { "E", E }, { "nu", 0.3 }, { "density", 1000 } } } };
}

json scene(const std::string& name, int steps)
{
    json s;
    s["dimension"] = 3;
    s["gravity"] = { 0, -9.81, 0 };
    s["solver"] = { { "residual_tolerance", 1e-8 } };
    if (name == "beam") {
        s["bodies"] = { body({ 0, 0, 0 }, { 1.0, 0.2, 0.2 }, { 20, 4, 4 }, 1e6) };
        s["dirichlet"] = { { { "body", "body" }, { "region", { { "min", { -1, -1, -1 } }, { "max", { 1e-6, 1, 1 } } } },
            { "displacement", { 0, 0, 0 } } } };
        s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", steps } };
    } else {
        s["bodies"] = { body({ 0, 0.005, 0 }, { 0.3, 0.105, 0.3 }, { 12, 4, 12 }, 1e5) };
        s["bodies"][0]["initial_velocity"] = { 0.2, -0.5, 0 };
        s["obstacles"]
            = { { { "name", "floor" }, { "plane", { { "point", { 0, 0, 0 } }, { "normal", { 0, 1, 0 } } } } } };
        s["contact"] = { { "dhat", 1e-3 }, { "kappa", 1e4 } };
        s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.002 }, { "steps", steps } };
    }
    return s;
}

StreamedObjective displacement_objective(double& value)
{
    StreamedObjective o;
    o.observe = [&value](const Simulator& sim, int k) {
        const Trajectory& tr = sim.trajectory();
        const VectorXd& x = k == 0 ? tr.initial_positions : tr.steps[size_t(k - 1)].positions;
        const double L = sim.bbox_diagonal();
        value += 0.5 * (x - flatten(sim.mesh().rest_positions)).squaredNorm() / (L * L);
    };
    o.seed = [](const Simulator& sim, int first, int last, StateSeed& seed) {
        const Trajectory& tr = sim.trajectory();
        const VectorXd X = flatten(sim.mesh().rest_positions);
        const double L = sim.bbox_diagonal();
        for (int k = first; k <= last; ++k) {
            const VectorXd& x = k == 0 ? tr.initial_positions : tr.steps[size_t(k - 1)].positions;
            seed.add_position(k, x - X, 1.0 / (L * L));
        }
    };
    return o;
}

} // namespace

int main(int argc, char** argv)
{
    const std::string name = argc > 1 ? argv[1] : "beam";
    const int steps = argc > 2 ? std::atoi(argv[2]) : 100;
    std::vector<int> strides;
    for (int i = 3; i < argc; ++i)
        strides.push_back(std::atoi(argv[i]));
    if (strides.empty())
        strides.push_back(0);
    if ((name != "beam" && name != "drop") || steps < 1) {
        std::fprintf(stderr, "usage: bench_checkpointing [beam|drop] [steps] [stride ...]\n");
        return 2;
    }
    const Scene sc = parse_scene(scene(name, steps), ".", name);
    ParameterRequest request;
    request.rest_positions = request.lame = request.density = request.initial_velocity = true;

    std::printf("%s: %ld vertices, %ld tets, %ld dofs, %d steps; J = sum_k |x_k - X|^2 / (2 L^2)\n", name.c_str(),
        long(sc.mesh.num_vertices()), long(sc.mesh.num_elements()), long(sc.mesh.num_dofs()), steps);
    std::printf("%-7s %6s %6s %5s %11s %11s %8s %9s %8s %10s %6s %10s\n", "mode", "stride", "stored", "bound", "bytes",
        "adj. bytes", "forward", "recompute", "adjoint", "recomputed", "ratio", "rel. diff.");
    {
        // Warm-up (first allocations, thread pools): a few untimed steps.
        Scene warm = sc;
        warm.time.steps = std::min(steps, 3);
        Simulator(warm).run();
    }
    ParameterGradient reference;
    std::vector<CheckpointSettings> runs(1);
    for (int s : strides) {
        CheckpointSettings c;
        c.mode = CheckpointSettings::Mode::STRIDE;
        c.stride = s;
        runs.push_back(c);
    }
    for (const CheckpointSettings& c : runs) {
        Simulator sim(sc);
        double value = 0;
        CheckpointStatistics st;
        ParameterGradient g;
        try {
            g = checkpointed_gradient(sim, displacement_objective(value), request, c, &st);
        } catch (const std::exception& e) {
            std::printf("failed: %s\n", e.what());
            return 1;
        }
        double diff = 0;
        if (c.mode == CheckpointSettings::Mode::NONE)
            reference = g;
        else
            for (const auto& [a, b] :
                { std::pair { &g.rest_positions, &reference.rest_positions }, std::pair { &g.mu, &reference.mu },
                    std::pair { &g.lambda, &reference.lambda }, std::pair { &g.density, &reference.density },
                    std::pair { &g.initial_velocity, &reference.initial_velocity } })
                diff = std::max(diff, (*a - *b).norm() / b->norm());
        std::printf("%-7s %6d %6d %5d %11zu %11zu %7.2fs %8.2fs %7.2fs %10d %6.2f %10.2e\n",
            c.mode == CheckpointSettings::Mode::NONE ? "full" : "stride", st.stride, st.peak_stored_states,
            st.bound_stored_states, st.peak_stored_bytes, st.adjoint.peak_adjoint_bytes, st.forward_time,
            st.recompute_time, st.adjoint_time, st.recomputed_steps, st.cost_ratio, diff);
        if (diff > 1e-10) {
            std::printf("the checkpointed gradient differs from the full-memory one\n");
            return 1;
        }
    }
    return 0;
}
