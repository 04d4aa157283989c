// Several objectives over one run: adjoint_gradients() (one backward sweep per objective, each
// step's adjoint system assembled and factorized once for all) against adjoint_gradient() once
// per objective. Prints the times and their ratio, and the largest difference between the two
// gradients (docs/performance.md "Several functionals over one run").
//
//   bench_adjoint_sweeps [objectives] [steps]
//
// The scene: a 3D block (12 x 12 x 12 cubes, 10,368 tets, 6,591 dofs) compressed by 15% between
// glued plates in `steps` static load steps (default 4), as a material test; the objectives:
// `objectives` (default 32) random linear functionals of the final positions, as the marker
// functionals of a Fisher matrix. Asserts nothing.

#include "adjoint/adjoint.hpp"
#include "forward/common/timer.hpp"
#include "forward/scene/scene.hpp"

#include <nlohmann/json.hpp>

#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

using namespace diffipc;
using json = nlohmann::json;

int main(int argc, char** argv)
{
    const int objectives = argc > 1 ? std::atoi(argv[1]) : 32;
    const int steps = argc > 2 ? std::atoi(argv[2]) : 4;
    json s;
    s["dimension"] = 3;
    s["bodies"] = { { { "name", "block" },
        { "mesh", { { "box", { { "min", { 0, 0, 0 } }, { "max", { 0.04, 0.04, 0.04 } }, { "cells", { 12, 12, 12 } } } } } },
        { "material", { { "model", "neo_hookean" }, { "E", 5e4 }, { "nu", 0.45 }, { "density", 1000 } } } } };
    s["dirichlet"] = { { { "body", "block" }, { "region", { { "min", { -1, -1, -1 } }, { "max", { 1, 1, 1e-6 } } } },
                           { "displacement", { 0, 0, 0 } } },
        { { "body", "block" }, { "region", { { "min", { -1, -1, 0.04 - 1e-6 } }, { "max", { 1, 1, 1 } } } },
            { "displacement", { 0, 0, "-0.006*t" } } } };
    s["time"] = { { "integrator", "static" }, { "dt", 1.0 / steps }, { "steps", steps } };
    s["solver"] = { { "residual_tolerance", 1e-9 } };
    Simulator sim(parse_scene(s, ".", "<bench>"));
    Timer forward;
    sim.run();
    const double forward_time = forward.seconds();
    if (sim.trajectory().final_status != StepStatus::CONVERGED) {
        std::fprintf(stderr, "the forward run failed\n");
        return 1;
    }
    const Index n = sim.mesh().num_dofs();
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    std::vector<StateSeed> seeds(static_cast<size_t>(objectives));
    for (StateSeed& seed : seeds) {
        seed.resize(steps);
        VectorXd a(n);
        for (Index i = 0; i < n; ++i)
            a[i] = u(rng);
        seed.add_position(steps, a);
    }
    ParameterRequest request;
    request.lame = request.rest_positions = true;
    Timer separate;
    std::vector<ParameterGradient> one_by_one;
    for (const StateSeed& seed : seeds)
        one_by_one.push_back(adjoint_gradient(sim, seed, request));
    const double separate_time = separate.seconds();
    Timer shared;
    const std::vector<ParameterGradient> together = adjoint_gradients(sim, seeds, request);
    const double shared_time = shared.seconds();
    double difference = 0;
    for (size_t i = 0; i < seeds.size(); ++i)
        difference = std::max(difference,
            (together[i].rest_positions - one_by_one[i].rest_positions).norm() / one_by_one[i].rest_positions.norm());
    std::printf("block 12^3 (10,368 tets, %ld dofs), %d static steps, %d objectives\n", long(n), steps, objectives);
    std::printf("forward run                     %8.3f s\n", forward_time);
    std::printf("adjoint_gradient per objective  %8.3f s  (%.3f s each)\n", separate_time, separate_time / objectives);
    std::printf("adjoint_gradients, shared       %8.3f s  (%.3f s each)\n", shared_time, shared_time / objectives);
    std::printf("ratio separate / shared         %8.2f\n", separate_time / shared_time);
    std::printf("largest relative difference of the gradients %.2e\n", difference);
    return 0;
}
