// Stiff and extreme cases must end with a reported status and never leave a
// non-finite or inverted committed state. Volumes are re-checked here from the
// recorded positions, independently of the solver's own bound.

#include "tests/forward/test_utils.hpp"

#include <gtest/gtest.h>

using namespace diffipc;
using nlohmann::json;

namespace {

struct Extreme {
    std::string name;
    double E, nu, dt;
    int steps;
    double velocity; // initial x velocity towards the fixed end (m/s)
    std::string integrator;
};

void check_committed_states(const Simulator& sim, const std::string& what)
{
    const Trajectory& tr = sim.trajectory();
    for (const StepRecord& r : tr.steps) {
        ASSERT_EQ(r.status, StepStatus::CONVERGED);
        ASSERT_TRUE(r.positions.allFinite()) << what << " step " << r.index;
        ASSERT_TRUE(r.velocities.allFinite()) << what << " step " << r.index;
        ASSERT_TRUE(std::isfinite(r.residual));
        const Positions x = unflatten(r.positions, sim.mesh().dim);
        for (Index e = 0; e < sim.mesh().num_elements(); ++e)
            ASSERT_GT(signed_volume(x, sim.mesh().elements, e), 0.0) << what << " step " << r.index << " element " << e;
    }
    if (tr.final_status != StepStatus::CONVERGED) {
        EXPECT_GT(tr.failed_step, 0);
        EXPECT_FALSE(tr.failure_message.empty());
        // The failed step left the committed state untouched.
        EXPECT_EQ(sim.steps_done(), tr.failed_step - 1);
    }
}

class ExtremeCase : public testing::TestWithParam<Extreme> { };

TEST_P(ExtremeCase, EndsWithStatusAndValidStates)
{
    const Extreme& c = GetParam();
    json s = test::box_scene(3, { 1.0, 0.2, 0.2 }, { 6, 1, 1 }, "neo_hookean", c.E, c.nu);
    s["gravity"] = { 0.0, -9.81, 0.0 };
    s["bodies"][0]["initial_velocity"] = { c.velocity, 0.0, 0.0 };
    s["dirichlet"] = { { { "body", 0 }, { "region", test::region({ -1, -1, -1 }, { 0, 1, 1 }) },
        { "displacement", { 0, 0, 0 } } } };
    s["time"] = { { "integrator", c.integrator }, { "dt", c.dt }, { "steps", c.steps } };
    s["solver"] = { { "residual_tolerance", 1e-8 }, { "max_iterations", 200 } };
    Simulator sim(test::make_scene(s));
    sim.run();
    check_committed_states(sim, c.name);
    // These cases are all within reach of the solver: they should converge.
    EXPECT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << sim.trajectory().failure_message;
}

INSTANTIATE_TEST_SUITE_P(Forward, ExtremeCase,
    testing::Values(Extreme { "soft_E1e3_dt01", 1e3, 0.495, 0.1, 5, 0.0, "implicit_euler" },
        Extreme { "soft_E1e3_dt1e5", 1e3, 0.495, 1e-5, 5, 0.0, "implicit_euler" },
        Extreme { "stiff_E1e11_dt01", 1e11, 0.495, 0.1, 5, 0.0, "implicit_euler" },
        Extreme { "stiff_E1e11_dt1e5", 1e11, 0.495, 1e-5, 5, 0.0, "implicit_euler" },
        Extreme { "stiff_E1e11_bdf2", 1e11, 0.3, 0.01, 5, 0.0, "bdf2" },
        Extreme { "soft_E1e3_newmark", 1e3, 0.495, 0.1, 5, 0.0, "newmark" },
        Extreme { "v50_into_wall", 1e5, 0.3, 0.01, 10, -50.0, "implicit_euler" },
        Extreme { "v50_into_wall_nearly_incompressible", 1e6, 0.495, 0.005, 10, -50.0, "implicit_euler" },
        Extreme { "v50_into_wall_bdf2", 1e5, 0.3, 0.01, 10, -50.0, "bdf2" },
        Extreme { "static_E1e11", 1e11, 0.495, 1.0, 2, 0.0, "static" }),
    [](const testing::TestParamInfo<Extreme>& info) { return info.param.name; });

// A failure must be transactional: the state after a failed step equals the
// last committed one, and the status says why.
TEST(Transactional, FailedStepLeavesStateUntouched)
{
    json s = test::box_scene(2, { 1.0, 0.2 }, { 5, 1 }, "neo_hookean", 1e5, 0.3);
    s["gravity"] = { 0.0, -9.81 };
    s["dirichlet"]
        = { { { "body", 0 }, { "region", test::region({ -1, -1 }, { 0, 1 }) }, { "displacement", { 0, 0 } } } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.05 }, { "steps", 3 } };
    s["solver"] = { { "residual_tolerance", 1e-12 }, { "max_iterations", 1 } }; // one iteration cannot reach 1e-12
    Simulator sim(test::make_scene(s));
    const VectorXd before = sim.positions();
    EXPECT_EQ(sim.step(), StepStatus::NEWTON_EXHAUSTED);
    EXPECT_EQ(sim.steps_done(), 0);
    EXPECT_EQ((sim.positions() - before).norm(), 0.0);
    EXPECT_EQ(sim.trajectory().final_status, StepStatus::NEWTON_EXHAUSTED);
    EXPECT_EQ(sim.last_attempt().status, StepStatus::NEWTON_EXHAUSTED);
}

TEST(Transactional, InvertedStartIsInvalidInitialState)
{
    json s = test::box_scene(2, { 1.0, 0.2 }, { 5, 1 }, "neo_hookean", 1e5, 0.3);
    // The Dirichlet value at t = 0 folds the fixed end over: the start is infeasible.
    s["dirichlet"] = { { { "body", 0 }, { "region", test::region({ -1, -1 }, { 0.2, 1 }) },
        { "displacement", { "0.5 - 2*x", 0 } } } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.05 }, { "steps", 1 } };
    Simulator sim(test::make_scene(s));
    EXPECT_EQ(sim.step(), StepStatus::INVALID_INITIAL_STATE);
    EXPECT_EQ(sim.steps_done(), 0);
}

} // namespace

namespace {

// A static solve of an unsupported body under gravity has no equilibrium: the Hessian is singular
// (rigid motions) and the load is not orthogonal to its null space. Where the factorization meets
// an exactly zero pivot both factorizations break down (LINEAR_BREAKDOWN); where round-off leaves
// a pivot of order 1e-16 instead, the LDL^T fallback returns a direction of order 1e16 that no
// step along descends (LINE_SEARCH_EXHAUSTED). Which of the two happens depends on the last bits
// of the assembled matrix; either way the step fails, says why, and commits nothing.
TEST(Transactional, UnsupportedStaticBodyFailsAndCommitsNothing)
{
    json s = test::box_scene(2, { 1.0, 0.2 }, { 4, 1 }, "neo_hookean", 1e5, 0.3);
    s["gravity"] = { 0.0, -9.81 };
    s["time"] = { { "integrator", "static" }, { "dt", 1.0 }, { "steps", 2 } };
    Simulator sim(test::make_scene(s));
    const VectorXd start = sim.positions();
    sim.run();
    const Trajectory& t = sim.trajectory();
    EXPECT_TRUE(t.final_status == StepStatus::LINEAR_BREAKDOWN || t.final_status == StepStatus::LINE_SEARCH_EXHAUSTED)
        << to_string(t.final_status);
    EXPECT_EQ(sim.steps_done(), 0);
    EXPECT_EQ(t.failed_step, 1);
    EXPECT_NE(t.failure_message.find(to_string(t.final_status)), std::string::npos) << t.failure_message;
    EXPECT_TRUE(sim.positions().allFinite());
    EXPECT_EQ(sim.positions(), start); // nothing committed
}

} // namespace

namespace {

// A block sliding (0.2 m/s) and falling (0.5 m/s) onto a soft pad with friction: with a fixed
// barrier stiffness far below the adaptive rule's minimum (2.4e9 here) Newton stalls at the
// first contact, and the failure names the stiffness as the likely cause (not before contact); a
// stiff enough fixed barrier (1e8) runs.
TEST(Transactional, ATooSoftFixedBarrierStallsAndTheMessageSaysSo)
{
    json s;
    s["dimension"] = 2;
    s["bodies"] = { test::box_body("pad", { 0, 0 }, { 0.6, 0.1 }, { 12, 2 }),
        test::box_body("block", { 0.2, 0.105 }, { 0.4, 0.155 }, { 4, 1 }) };
    s["bodies"][0]["material"]["density"] = 500;
    s["bodies"][1]["material"]["E"] = 1e6;
    s["bodies"][1]["material"]["density"] = 2000;
    s["bodies"][1]["initial_velocity"] = { 0.2, -0.5 };
    s["dirichlet"]
        = { { { "body", 0 }, { "region", test::region({ -1, -1 }, { 2, 1e-6 }) }, { "displacement", { 0, 0 } } } };
    s["gravity"] = { 0, -9.81 };
    s["friction"] = { { "coefficient", 0.3 }, { "eps_v", 0.01 } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.005 }, { "steps", 4 } };
    s["solver"] = { { "max_iterations", 100 } };
    for (double kappa : { 1e5, 1e8 }) {
        s["contact"] = { { "dhat", 2e-3 }, { "kappa", kappa } };
        Simulator sim(test::make_scene(s));
        sim.run();
        const Trajectory& t = sim.trajectory();
        if (kappa == 1e5) {
            EXPECT_EQ(t.final_status, StepStatus::NEWTON_EXHAUSTED);
            EXPECT_NE(
                t.failure_message.find("fixed contact.kappa 100000 is below 1/100 of the adaptive rule's minimum"),
                std::string::npos)
                << t.failure_message;
        } else {
            EXPECT_EQ(t.final_status, StepStatus::CONVERGED) << t.failure_message;
        }
    }
    // A step that stalls before the bodies touch (the block still 5 mm up) does not blame the barrier.
    s["contact"] = { { "dhat", 2e-3 }, { "kappa", 1e5 } };
    s["solver"] = { { "max_iterations", 1 }, { "residual_tolerance", 1e-14 } };
    Simulator sim(test::make_scene(s));
    sim.run();
    EXPECT_EQ(sim.trajectory().final_status, StepStatus::NEWTON_EXHAUSTED);
    EXPECT_EQ(sim.trajectory().failure_message.find("kappa"), std::string::npos) << sim.trajectory().failure_message;
}

} // namespace
