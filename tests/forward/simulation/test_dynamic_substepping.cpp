// Automatic step control in dynamic scenes (time.adaptive, forward/simulation/dynamic_substepping.cpp):
// a dynamic step whose solve fails is taken again in sub-steps of its time increment, each a step
// of the integrator from the last sub-step's state.

#include "forward/common/error.hpp"
#include "forward/contact/intersection.hpp"
#include "tests/forward/contact/contact_scenes.hpp"
#include "tests/forward/test_utils.hpp"

#include <gtest/gtest.h>

#include <string>

using namespace diffipc;
using json = nlohmann::json;
using test::falling_box;

namespace {

/// No inverted element and no intersection at x, by checks independent of the solver's.
void expect_valid(const Simulator& sim, const VectorXd& x)
{
    const Positions X = unflatten(x, sim.scene().dim);
    EXPECT_EQ(count_inverted_elements(sim.mesh(), X), 0);
    EXPECT_EQ(find_intersection(sim.contact()->collision_mesh(), X, /*all_pairs=*/true), "");
}

} // namespace

TEST(DynamicSubstepping, GivenSubstepsRepeatARunWithThoseSteps)
{
    // Steps of 0.02 s, each taken in n equal sub-steps (SimulationParameters::substeps), against a
    // run of 0.02 / n s steps (the obstacle's motion and gravity enter at the sub-steps' end
    // times): positions and velocities agree at every 0.02 s. Implicit Euler and Newmark, 2D and
    // 3D; the box lands in the first step.
    for (int dim : { 2, 3 })
        for (const char* integrator : { "implicit_euler", "newmark" })
            for (int n : { 2, 4 }) {
                SCOPED_TRACE(std::to_string(dim) + "D " + integrator + ", " + std::to_string(n) + " sub-steps");
                const double dt = 0.02;
                SimulationParameters p;
                for (int k = 1; k <= 3; ++k) {
                    p.substeps.emplace_back();
                    for (int j = 1; j <= n; ++j)
                        p.substeps.back().push_back((k - 1) * dt + j * dt / n);
                }
                Simulator coarse(test::make_scene(falling_box(dim, integrator, dt, 3)), p);
                const Trajectory& tr = coarse.run();
                ASSERT_EQ(tr.final_status, StepStatus::CONVERGED) << tr.failure_message;
                Simulator fine(test::make_scene(falling_box(dim, integrator, dt / n, 3 * n)));
                const Trajectory& ref = fine.run();
                ASSERT_EQ(ref.final_status, StepStatus::CONVERGED) << ref.failure_message;
                ASSERT_GT(ref.step(n).active_contacts, 0) << "the box does not land: the check would miss contact";
                for (int k = 1; k <= 3; ++k) {
                    SCOPED_TRACE(k);
                    const StepRecord& r = tr.step(k);
                    ASSERT_EQ(r.substeps, n);
                    ASSERT_EQ(int(r.path.size()), n - 1);
                    EXPECT_EQ(r.time, ref.step(k * n).time);
                    EXPECT_LE((r.positions - ref.step(k * n).positions).lpNorm<Eigen::Infinity>(), 1e-9);
                    EXPECT_LE((r.velocities - ref.step(k * n).velocities).lpNorm<Eigen::Infinity>(), 1e-7);
                    for (int j = 1; j < n; ++j) {
                        const StepRecord::SubState& sub = r.path[size_t(j - 1)];
                        EXPECT_NEAR(sub.time, ref.step((k - 1) * n + j).time, 1e-15);
                        EXPECT_LE(
                            (sub.positions - ref.step((k - 1) * n + j).positions).lpNorm<Eigen::Infinity>(), 1e-9);
                    }
                }
            }
}

TEST(DynamicSubstepping, FailedStepsAreSubsteppedValidAndRepeatable)
{
    // With at most 9 Newton iterations per solve, the landing step fails as one step of 0.04 s
    // (it takes 12 in 2D, 10 in 3D) and is taken in sub-steps (time.adaptive). Every committed state and sub-state is
    // free of inversions and intersections by the independent exact checks, the velocity is that of the last sub-step,
    // and a run built from the run's parameters() takes the same sub-steps to the same states.
    // Implicit Euler only: under Newmark this landing takes 11 or more iterations at every step
    // size (its sub-steps with Newmark are checked by the test above and the adjoint's).
    for (int dim : { 2, 3 })
        for (const char* integrator : { "implicit_euler" }) {
            SCOPED_TRACE(std::to_string(dim) + "D " + integrator);
            json s = falling_box(dim, integrator, 0.04, 2);
            s["contact"]["kappa"] = 1e7;
            s["time"]["adaptive"] = { { "min_increment", 0.04 / 64 } };
            s["solver"]["max_iterations"] = 9;
            Simulator sim(test::make_scene(s));
            const Trajectory& tr = sim.run();
            ASSERT_EQ(tr.final_status, StepStatus::CONVERGED) << tr.failure_message;
            ASSERT_GT(tr.totals.substepped_steps, 0) << "no step was sub-stepped: the check would be plain";
            for (const StepRecord& r : tr.steps) {
                SCOPED_TRACE(r.index);
                expect_valid(sim, r.positions);
                EXPECT_EQ(int(r.substep_times.size()), r.substeps);
                if (r.substeps == 0)
                    continue;
                EXPECT_EQ(int(r.path.size()), r.substeps - 1);
                EXPECT_EQ(r.substep_times.back(), r.time);
                for (const StepRecord::SubState& sub : r.path)
                    expect_valid(sim, sub.positions);
                if (std::string(integrator) == "implicit_euler") {
                    const double h = r.time - r.path.back().time;
                    EXPECT_LE(
                        (r.velocities - (r.positions - r.path.back().positions) / h).lpNorm<Eigen::Infinity>(), 1e-9);
                }
            }
            Simulator replay(test::make_scene(s), sim.parameters());
            const Trajectory& again = replay.run();
            ASSERT_EQ(again.final_status, StepStatus::CONVERGED) << again.failure_message;
            for (int k = 1; k <= tr.committed(); ++k) {
                EXPECT_EQ(again.step(k).substep_times, tr.step(k).substep_times);
                EXPECT_LE((again.step(k).positions - tr.step(k).positions).lpNorm<Eigen::Infinity>(), 1e-12);
                EXPECT_LE((again.step(k).velocities - tr.step(k).velocities).lpNorm<Eigen::Infinity>(), 1e-9);
            }
        }
}

TEST(DynamicSubstepping, AStepThatCannotBeTakenEndsWithAStatusAtTheMinimumIncrement)
{
    json s = falling_box(2, "implicit_euler", 0.02, 4);
    s["time"]["adaptive"] = { { "min_increment", 0.02 / 8 } };
    s["solver"]["max_iterations"] = 1;
    Simulator sim(test::make_scene(s));
    const Trajectory& tr = sim.run();
    ASSERT_NE(tr.final_status, StepStatus::CONVERGED);
    EXPECT_NE(tr.failure_message.find("would cut the increment below time.adaptive.min_increment"), std::string::npos)
        << tr.failure_message;
    EXPECT_EQ(tr.committed(), tr.failed_step - 1);
}

TEST(DynamicSubstepping, GivenSubstepsAreCheckedNamingTheField)
{
    const auto message = [](const json& scene, const SimulationParameters& p) {
        try {
            Simulator sim(test::make_scene(scene), p);
        } catch (const InputError& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    const json s = falling_box(2, "implicit_euler", 0.02, 2);
    SimulationParameters p;
    p.substeps = { { 0.01, 0.02 }, {} };
    EXPECT_EQ(message(s, p), "no error");
    p.substeps = { { 0.01, 0.02 } };
    EXPECT_NE(message(s, p).find("substeps: expected 2 entries"), std::string::npos) << message(s, p);
    p.substeps = { { 0.01, 0.019 }, {} };
    EXPECT_NE(message(s, p).find("substeps: [0]: the last sub-step must end at t_1"), std::string::npos)
        << message(s, p);
    p.substeps = { {}, { 0.03, 0.025, 0.04 } };
    EXPECT_NE(message(s, p).find("substeps: [1]: the sub-steps' end times must increase"), std::string::npos)
        << message(s, p);
    json bdf2 = s;
    bdf2["time"]["integrator"] = "bdf2";
    p.substeps = { { 0.01, 0.02 }, {} };
    EXPECT_NE(message(bdf2, p).find("one-step dynamic integrator"), std::string::npos) << message(bdf2, p);
    bdf2["time"]["adaptive"] = true;
    try {
        test::make_scene(bdf2);
        FAIL() << "BDF2 with time.adaptive was accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("time.adaptive: automatic step control needs a one-step integrator"),
            std::string::npos)
            << e.what();
    }
}
