// A periodic cell's homogenized stress (objectives/macro_stress.hpp) as an objective: its value
// against the simulator's record, its state and explicit gradients against central differences,
// and its gradient through the adjoint against whole forward runs (material, density, macro).

#include "objectives/macro_stress.hpp"

#include "objective_fd.hpp"
#include "objectives/objective_json.hpp"
#include "objectives/time_aggregation.hpp"
#include "tests/forward/periodic/post_cell.hpp"
#include "through_adjoint.hpp"

#include <cstdio>

using namespace diffipc;
using json = nlohmann::json;
using test::Block;

TEST(MacroStress, ValueIsTheRecordedAverageStressAndItsGradientsMatchDifferences)
{
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE(dim);
        const test::Run run = test::run_cell(test::compressed_periodic_cell(dim, "static"));
        for (int i = 0; i < dim; ++i)
            for (int j = 0; j < dim; ++j) {
                const MacroStress f(i, j, dim);
                const StepRecord& last = run.trajectory.steps.back();
                const StateRef state { last.index, last.time, last.positions, last.velocities };
                EXPECT_NEAR(f.value(*run.sim, state), last.macro_stress[i * dim + j], 1e-9 * last.macro_stress.norm());
            }
        const TimeAggregation J(std::make_unique<MacroStress>(0, 0, dim), TimeMode::SUM);
        ASSERT_LT(J.value(*run.sim, run.trajectory), 0); // compression
        test::check_state_gradient(J, run, 11, 1e-6);
        test::check_parameter_gradient(J, run, Block::REST_POSITIONS, 19, 1e-6);
        test::check_parameter_gradient(J, run, Block::MU, 23, 1e-6);
        test::check_parameter_gradient(J, run, Block::LAMBDA, 29, 1e-6);
    }
}

TEST(MacroStress, GradientsThroughTheAdjointMatchWholeRuns)
{
    // The homogenized stress G_xx summed over the steps: dJ/dp through the forward and the
    // adjoint of the periodic cell, against central differences of whole runs.
    for (int dim : { 2, 3 })
        for (const char* integrator : { "static", "implicit_euler" }) {
            SCOPED_TRACE(std::to_string(dim) + "D " + integrator);
            const json objective = { { "type", "macro_stress" }, { "component", "xx" }, { "time", "sum" } };
            test::check_through_adjoint(test::compressed_periodic_cell(dim, integrator), objective,
                { Block::REST_POSITIONS, Block::MU, Block::LAMBDA, Block::DENSITY, Block::MACRO }, 1e-3, 1e-6, 0.1);
        }
}

TEST(MacroStress, WithContactAcrossTheCellBoundaryItsGradientsMatchWholeRuns)
{
    // The post cell (tests/forward/periodic/post_cell.hpp) at G_yy = -0.12: its posts press on
    // the next cell's across the boundary, and the stress P_yy has the barrier's part. Its
    // explicit partials at the contact state, then dJ/dp through the adjoint against whole runs
    // (fixed kappa; the Taylor steps keep the sliding faces' vertices from passing each other).
    for (int dim : { 2, 3 })
        for (const char* integrator : { "static", "implicit_euler" }) {
            SCOPED_TRACE(std::to_string(dim) + "D " + integrator);
            const std::string path = "/tmp/diffipc_macro_post_cell_" + std::to_string(::getpid()) + ".msh";
            json s = test::post_cell_scene(dim, path, -0.12, 2, 1e7);
            s["time"]["integrator"] = integrator;
            s["solver"]["residual_tolerance"] = 1e-11;
            if (std::string(integrator) == "static") {
                const test::Run run = test::run_cell(s);
                ASSERT_GT(run.trajectory.steps.back().active_contacts, 0);
                const TimeAggregation J(std::make_unique<MacroStress>(1, 1, dim), TimeMode::SUM);
                test::check_state_gradient(J, run, 13, 1e-6);
                // The barrier has no Lame partial (the test above checks the elastic one); its
                // shape partial (the lever, the mollifier thresholds through the images) is here.
                test::check_parameter_gradient(J, run, Block::REST_POSITIONS, 17, 1e-6);
            }
            const json objective = { { "type", "macro_stress" }, { "component", "yy" }, { "time", "sum" } };
            test::check_through_adjoint(s, objective, { Block::REST_POSITIONS, Block::MU, Block::LAMBDA, Block::MACRO },
                2.5e-4, 1e-5, 0.1, 1e7);
            std::remove(path.c_str());
        }
}

TEST(MacroStress, ProblemFileErrorsNameTheField)
{
    Simulator periodic(test::make_scene(test::compressed_periodic_cell(2, "static")));
    const auto message = [](const json& j, const Simulator& sim) { return test::objective_error(j, sim); };
    EXPECT_EQ(message({ { "type", "macro_stress" }, { "component", "xy" } }, periodic), "no error");
    EXPECT_EQ(message({ { "type", "macro_stress" }, { "component", "xz" } }, periodic),
        "objective.component: expected two of xy (row, column), got \"xz\"");
    Simulator plain(test::make_scene(test::box_scene(2, { 1, 1 }, { 2, 2 })));
    EXPECT_EQ(message({ { "type", "macro_stress" }, { "component", "xx" } }, plain),
        "objective.type: macro_stress needs a periodic cell (the scene's \"periodic\")");
}
