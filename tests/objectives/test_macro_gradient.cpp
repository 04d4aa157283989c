// A periodic cell's macro displacement gradient (objectives/macro_gradient.hpp) as an objective:
// its value against the simulator's record, its state and explicit gradients against central
// differences, its gradient through the adjoint against whole runs (also with contact across the
// cell's boundary), and tracking it (and the stress) at listed steps from a problem file.

#include "objectives/macro_gradient.hpp"

#include "objective_fd.hpp"
#include "objectives/macro_stress.hpp"
#include "objectives/objective_json.hpp"
#include "objectives/state_tracking.hpp"
#include "objectives/time_aggregation.hpp"
#include "tests/forward/periodic/post_cell.hpp"
#include "through_adjoint.hpp"

#include <cstdio>

using namespace diffipc;
using json = nlohmann::json;
using test::Block;

TEST(MacroGradient, ValueIsTheRecordedGradientAndItsGradientsMatchDifferences)
{
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE(dim);
        const test::Run run = test::run_cell(test::compressed_periodic_cell(dim, "static"));
        const StepRecord& last = run.trajectory.steps.back();
        const StateRef state { last.index, last.time, last.positions, last.velocities };
        for (int i = 0; i < dim; ++i)
            for (int j = 0; j < dim; ++j)
                EXPECT_NEAR(MacroGradient(i, j, dim).value(*run.sim, state), last.macro_gradient[i * dim + j], 1e-12);
        // G_yy is free: it moves under G_xx = -0.2 t and gravity.
        const TimeAggregation J(std::make_unique<MacroGradient>(1, 1, dim), TimeMode::SUM);
        ASSERT_GT(std::abs(J.value(*run.sim, run.trajectory)), 1e-3);
        test::check_state_gradient(J, run, 11, 1e-6);
        test::check_parameter_gradient(J, run, Block::REST_POSITIONS, 19, 1e-6);
    }
}

TEST(MacroGradient, GradientsThroughTheAdjointMatchWholeRuns)
{
    for (int dim : { 2, 3 })
        for (const char* integrator : { "static", "implicit_euler" }) {
            SCOPED_TRACE(std::to_string(dim) + "D " + integrator);
            const json objective = { { "type", "macro_gradient" }, { "component", "yy" }, { "time", "sum" } };
            test::check_through_adjoint(test::compressed_periodic_cell(dim, integrator), objective,
                { Block::REST_POSITIONS, Block::MU, Block::LAMBDA, Block::DENSITY, Block::MACRO }, 1e-3, 1e-6, 0.1);
        }
}

TEST(MacroGradient, WithContactAcrossTheCellBoundaryItsGradientsMatchWholeRuns)
{
    // The post cell pressed to G_yy = -0.12 (its posts touch across the boundary): the free G_xx.
    // 2D (the 3D contact path of the same adjoint is MacroStress's test).
    for (int dim : { 2 }) {
        const std::string path = "/tmp/diffipc_macro_gradient_post_" + std::to_string(::getpid()) + ".msh";
        json s = test::post_cell_scene(dim, path, -0.12, 2, 1e7);
        s["solver"]["residual_tolerance"] = 1e-11;
        const test::Run run = test::run_cell(s);
        ASSERT_GT(run.trajectory.steps.back().active_contacts, 0);
        const json objective = { { "type", "macro_gradient" }, { "component", "xx" }, { "time", "sum" } };
        test::check_through_adjoint(
            s, objective, { Block::REST_POSITIONS, Block::MU, Block::LAMBDA, Block::MACRO }, 2.5e-4, 1e-5, 0.1, 1e7);
        std::remove(path.c_str());
    }
}

TEST(MacroGradient, TrackingAtListedStepsFromAProblemFile)
{
    // {"targets": [...], "steps": [...], "sigma": s}: J = 1/2 sum ((f_k - y_k) / s)^2, for the
    // stress and the gradient alike; its gradient through the adjoint against whole runs.
    const json scene = test::compressed_periodic_cell(2, "static");
    const test::Run run = test::run_cell(scene);
    const auto& steps = run.trajectory.steps;
    for (const char* type : { "macro_stress", "macro_gradient" }) {
        SCOPED_TRACE(type);
        const bool stress = std::string(type) == "macro_stress";
        // The prescribed component of the stress (P_yy = 0 at the static equilibrium: G_yy is
        // free) and the free one of the gradient; steps[k - 1] is step k's record.
        const int c = stress ? 0 : 3;
        const double f1 = stress ? steps[0].macro_stress[c] : steps[0].macro_gradient[c];
        const double f3 = stress ? steps[2].macro_stress[c] : steps[2].macro_gradient[c];
        const double sigma = std::abs(f3);
        const json objective = { { "type", type }, { "component", stress ? "xx" : "yy" }, { "steps", { 1, 3 } },
            { "targets", { 0.5 * f1, 2 * f3 } }, { "sigma", sigma } };
        const auto J = parse_objective(objective, "objective", *run.sim);
        const double expected = 0.5 * (std::pow(0.5 * f1 / sigma, 2) + std::pow(f3 / sigma, 2));
        EXPECT_NEAR(J->value(*run.sim, run.trajectory), expected, 1e-12 * expected);
        test::check_through_adjoint(scene, objective, { Block::REST_POSITIONS, Block::MU, Block::MACRO }, 1e-3, 1e-6);
    }
    // A key that belongs to the other form is named.
    const auto message = [&](const json& j) { return test::objective_error(j, *run.sim); };
    EXPECT_EQ(message({ { "type", "macro_gradient" }, { "component", "yy" }, { "sigma", 1 } }),
        "objective.sigma: only applies with \"targets\"");
    EXPECT_EQ(
        message({ { "type", "macro_gradient" }, { "component", "yy" }, { "targets", { 0, 0, 0 } }, { "time", "sum" } }),
        "objective.time: does not apply with \"targets\" (the listed states are compared)");
}
