// Automatic load stepping (time.adaptive, forward/simulation/load_stepping.cpp): a static step
// whose solve fails is solved again in sub-steps of its load increment.

#include "forward/common/error.hpp"
#include "forward/contact/intersection.hpp"
#include "forward/io/trajectory_reader.hpp"
#include "forward/io/trajectory_writer.hpp"
#include "tests/forward/test_utils.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <string>

using namespace diffipc;
using json = nlohmann::json;

namespace {

/// A neo-Hookean block [0, 1]^dim on its bottom face, its top face pushed down by
/// `compression` (a fraction of its height) in `steps` static steps; Newton may take at most
/// `max_iterations` per solve, so that one large increment fails and small ones converge.
json compressed_block(int dim, double compression, int steps, int max_iterations, const json& adaptive = nullptr)
{
    json s = dim == 2 ? test::box_scene(2, { 1, 1 }, { 4, 4 }, "neo_hookean", 1e5, 0.3, 1000)
                      : test::box_scene(3, { 1, 1, 1 }, { 2, 2, 2 }, "neo_hookean", 1e5, 0.3, 1000);
    const json zero = dim == 2 ? json { 0, 0 } : json { 0, 0, 0 };
    json down = zero;
    down[1] = std::to_string(-compression) + "*t";
    std::vector<double> top_lo(size_t(dim), -1), top_hi(size_t(dim), 2), bottom_hi(size_t(dim), 2);
    top_lo[1] = 1 - 1e-6;
    bottom_hi[1] = 1e-6;
    s["dirichlet"] = { { { "body", 0 }, { "region", test::region(std::vector<double>(size_t(dim), -1), bottom_hi) },
                           { "displacement", zero } },
        { { "body", 0 }, { "region", test::region(top_lo, top_hi) }, { "displacement", down } } };
    s["time"] = { { "integrator", "static" }, { "dt", 1.0 / steps }, { "steps", steps } };
    if (!adaptive.is_null())
        s["time"]["adaptive"] = adaptive;
    s["solver"] = { { "residual_tolerance", 1e-10 }, { "max_iterations", max_iterations } };
    return s;
}

double apex_height(const Simulator& sim, const VectorXd& x)
{
    Index apex = 0;
    const VectorXd& X = sim.trajectory().initial_positions;
    for (Index v = 0; v < X.size() / 2; ++v)
        if (X[2 * v + 1] > X[2 * apex + 1])
            apex = v;
    return x[2 * apex + 1];
}

/// Every step of `run` converged to the reference's equilibrium at the same time (within 1e-7 m),
/// with no inverted element and no intersection by checks independent of the solver's.
void expect_reference_states(const Simulator& run, const Simulator& reference)
{
    const Trajectory& tr = run.trajectory();
    ASSERT_EQ(tr.committed(), reference.trajectory().committed());
    for (int k = 1; k <= tr.committed(); ++k) {
        SCOPED_TRACE(k);
        const VectorXd& x = tr.step(k).positions;
        EXPECT_LE(tr.step(k).residual, run.scene().solver.residual_tolerance);
        EXPECT_EQ(tr.step(k).time, reference.trajectory().step(k).time);
        EXPECT_LE((x - reference.trajectory().step(k).positions).lpNorm<Eigen::Infinity>(), 1e-7);
        const Positions X = unflatten(x, run.scene().dim);
        EXPECT_EQ(count_inverted_elements(run.mesh(), X), 0);
        EXPECT_EQ(find_intersection(run.contact()->collision_mesh(), X, /*all_pairs=*/true), "");
    }
}

} // namespace

TEST(LoadStepping, FailedStepsConvergeInSubstepsToTheSameEquilibrium)
{
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE(dim);
        // Without the option the 60% compression in 2 steps of at most 4 Newton iterations fails.
        Simulator plain(test::make_scene(compressed_block(dim, 0.6, 2, 4)));
        EXPECT_NE(plain.run().final_status, StepStatus::CONVERGED);
        // With it, every step converges, some in sub-steps.
        Simulator adaptive(test::make_scene(compressed_block(dim, 0.6, 2, 4, true)));
        const Trajectory& tr = adaptive.run();
        ASSERT_EQ(tr.final_status, StepStatus::CONVERGED) << tr.failure_message;
        ASSERT_EQ(tr.committed(), 2);
        EXPECT_GT(tr.totals.substepped_steps, 0);
        EXPECT_GE(tr.totals.cuts, tr.totals.substepped_steps);
        // The requested times are hit exactly, and each state is the equilibrium at its time: the
        // same as a run of 32 small steps (unlimited iterations) at t = 0.5 and 1.
        EXPECT_EQ(tr.steps[0].time, 0.5);
        EXPECT_EQ(tr.steps[1].time, 1.0);
        Simulator fine(test::make_scene(compressed_block(dim, 0.6, 32, 100)));
        const Trajectory& ref = fine.run();
        ASSERT_EQ(ref.final_status, StepStatus::CONVERGED);
        for (int k : { 1, 2 }) {
            const VectorXd& x = tr.steps[size_t(k - 1)].positions;
            const VectorXd& y = ref.steps[size_t(16 * k - 1)].positions;
            EXPECT_LE((x - y).norm(), 1e-8 * y.norm()) << "step " << k;
            const StepRecord& r = tr.steps[size_t(k - 1)];
            if (r.substeps > 0) {
                EXPECT_GT(r.min_increment, 0);
                EXPECT_LE(r.min_increment, 0.25 + 1e-15); // the first sub-step is at most half the step
            }
        }
    }
}

TEST(LoadStepping, SceneThatNeedsNoSubstepIsUnchangedBitForBit)
{
    Simulator plain(test::make_scene(compressed_block(2, 0.1, 2, 100)));
    Simulator adaptive(test::make_scene(compressed_block(2, 0.1, 2, 100, true)));
    const Trajectory& a = plain.run();
    const Trajectory& b = adaptive.run();
    ASSERT_EQ(a.final_status, StepStatus::CONVERGED);
    ASSERT_EQ(b.final_status, StepStatus::CONVERGED);
    for (size_t k = 0; k < a.steps.size(); ++k) {
        EXPECT_EQ(a.steps[k].positions, b.steps[k].positions);
        EXPECT_EQ(b.steps[k].substeps, 0);
        EXPECT_EQ(b.steps[k].cuts, 0);
    }
    EXPECT_EQ(b.totals.substepped_steps, 0);
}

TEST(LoadStepping, AnImpossibleLoadEndsWithAStatusAtTheMinimumIncrement)
{
    // 130% compression cannot be reached without inverting elements: the run must end, with a
    // failure status and a message that says how far the sub-steps got.
    Simulator sim(test::make_scene(
        compressed_block(2, 1.3, 1, 20, { { "min_increment", 1e-3 }, { "cut", 0.5 }, { "growth", 2 } })));
    const Trajectory& tr = sim.run();
    EXPECT_NE(tr.final_status, StepStatus::CONVERGED);
    EXPECT_EQ(tr.committed(), 0);
    EXPECT_NE(tr.failure_message.find("automatic load stepping took"), std::string::npos) << tr.failure_message;
    EXPECT_NE(tr.failure_message.find("time.adaptive.min_increment = 0.001 s"), std::string::npos)
        << tr.failure_message;
    EXPECT_EQ(sim.positions(), sim.trajectory().initial_positions) << "a failed step leaves the state untouched";
}

TEST(LoadStepping, DisplacementControlPassesASnapThroughThatSubstepsCannot)
{
    // Reference: Newton with 100 iterations per step crosses the snap in one solve.
    Simulator reference(test::make_scene(test::shallow_arch(4, 100, nullptr)));
    ASSERT_EQ(reference.run().final_status, StepStatus::CONVERGED);
    ASSERT_GT(apex_height(reference, reference.trajectory().step(2).positions), 0.98);
    ASSERT_LT(apex_height(reference, reference.trajectory().step(3).positions), 0.93) << "the arch snaps in step 3";

    // With 8 iterations per solve, sub-steps get to the limit point (t ~ 0.106 s) and no further.
    Simulator substeps_only(test::make_scene(
        test::shallow_arch(4, 8, { { "displacement_control", false }, { "relaxation", false } })));
    const Trajectory& failed = substeps_only.run();
    EXPECT_EQ(failed.committed(), 2);
    EXPECT_EQ(failed.failed_step, 3);
    EXPECT_NE(failed.failure_message.find("time.adaptive.min_increment"), std::string::npos)
        << failed.failure_message;

    // Displacement control follows the equilibria along the load through the limit point.
    Simulator controlled(test::make_scene(test::shallow_arch(4, 8, true)));
    const Trajectory& tr = controlled.run();
    ASSERT_EQ(tr.final_status, StepStatus::CONVERGED) << tr.failure_message;
    EXPECT_GT(tr.step(3).control_steps, 0);
    EXPECT_EQ(tr.step(3).relaxation_steps, 0) << "the control alone got there";
    EXPECT_EQ(tr.totals.control_steps, tr.step(3).control_steps);
    expect_reference_states(controlled, reference);

    // The control steps are written to trajectory.h5 and read back.
    const std::string path = testing::TempDir() + "load_stepping_control.h5";
    write_hdf5(path, controlled.mesh(), tr, true, true);
    const StoredTrajectory stored = read_trajectory(path);
    for (int k = 1; k <= 4; ++k)
        EXPECT_EQ(stored.trajectory.step(k).control_steps, tr.step(k).control_steps);
    std::remove(path.c_str());
}

TEST(LoadStepping, RelaxationPassesASnapThroughToo)
{
    // Without displacement control, proximal relaxation at t_3 finds the snapped equilibrium.
    Simulator reference(test::make_scene(test::shallow_arch(4, 100, nullptr)));
    ASSERT_EQ(reference.run().final_status, StepStatus::CONVERGED);
    Simulator relaxed(test::make_scene(test::shallow_arch(4, 8, { { "displacement_control", false } })));
    const Trajectory& tr = relaxed.run();
    ASSERT_EQ(tr.final_status, StepStatus::CONVERGED) << tr.failure_message;
    EXPECT_GT(tr.step(3).relaxation_steps, 0);
    EXPECT_EQ(tr.step(3).control_steps, 0);
    expect_reference_states(relaxed, reference);
    const std::string path = testing::TempDir() + "load_stepping_relaxation.h5";
    write_hdf5(path, relaxed.mesh(), tr, true, true);
    EXPECT_EQ(read_trajectory(path).trajectory.step(3).relaxation_steps, tr.step(3).relaxation_steps);
    std::remove(path.c_str());
}

TEST(LoadStepping, DisplacementControlNeedsALoadThatChanges)
{
    // Prescribed displacements only: the failure says why displacement control could not help.
    Simulator sim(test::make_scene(
        compressed_block(2, 1.3, 1, 20, { { "min_increment", 1e-3 }, { "cut", 0.5 }, { "growth", 2 } })));
    const Trajectory& tr = sim.run();
    EXPECT_NE(tr.final_status, StepStatus::CONVERGED);
    EXPECT_NE(tr.failure_message.find("displacement control needs a load"), std::string::npos) << tr.failure_message;
    // Relaxation cannot reach an impossible state either, and says so.
    EXPECT_NE(tr.failure_message.find("relaxation took"), std::string::npos) << tr.failure_message;
}

TEST(LoadStepping, PrescribedOverridesAreInterpolatedWithinTheStep)
{
    // With prescribed displacements given as parameters (the adjoint's g_k), the sub-steps
    // interpolate them from the committed step: the same equilibrium as the expressions give.
    const Scene scene = test::make_scene(compressed_block(2, 0.6, 2, 4, true));
    Simulator by_expression(scene);
    ASSERT_EQ(by_expression.run().final_status, StepStatus::CONVERGED);
    Simulator by_parameters(scene, by_expression.parameters());
    const Trajectory& tr = by_parameters.run();
    ASSERT_EQ(tr.final_status, StepStatus::CONVERGED);
    EXPECT_GT(tr.totals.substepped_steps, 0);
    for (size_t k = 0; k < tr.steps.size(); ++k) {
        const VectorXd& x = by_expression.trajectory().steps[k].positions;
        EXPECT_LE((tr.steps[k].positions - x).norm(), 1e-9 * x.norm()) << "step " << k + 1;
    }
}

TEST(LoadStepping, SubstepCountsAreWrittenAndReadBack)
{
    Simulator sim(test::make_scene(compressed_block(2, 0.6, 2, 4, true)));
    const Trajectory& tr = sim.run();
    ASSERT_EQ(tr.final_status, StepStatus::CONVERGED);
    const std::string path = testing::TempDir() + "load_stepping.h5";
    write_hdf5(path, sim.mesh(), tr, false, true);
    const StoredTrajectory stored = read_trajectory(path);
    ASSERT_EQ(stored.trajectory.committed(), 2);
    for (int k = 1; k <= 2; ++k) {
        EXPECT_EQ(stored.trajectory.step(k).substeps, tr.step(k).substeps);
        EXPECT_EQ(stored.trajectory.step(k).cuts, tr.step(k).cuts);
        EXPECT_EQ(stored.trajectory.step(k).min_increment, tr.step(k).min_increment);
    }
    std::remove(path.c_str());
}

TEST(LoadStepping, SettingsAreCheckedNamingTheField)
{
    const auto message = [](const json& s) {
        try {
            test::make_scene(s);
        } catch (const InputError& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    EXPECT_EQ(message(compressed_block(2, 0.1, 2, 10, true)), "no error");
    EXPECT_EQ(message(compressed_block(2, 0.1, 2, 10, false)), "no error");
    json s = compressed_block(2, 0.1, 2, 10, true);
    s["time"]["integrator"] = "implicit_euler";
    EXPECT_EQ(message(s), "no error"); // tests/forward/simulation/test_dynamic_substepping.cpp
    s["time"]["integrator"] = "bdf2";
    EXPECT_NE(message(s).find("time.adaptive: automatic step control needs a one-step integrator"),
        std::string::npos)
        << message(s);
    EXPECT_NE(message(compressed_block(2, 0.1, 2, 10, { { "cut", 1.5 } })).find("time.adaptive.cut"),
        std::string::npos);
    EXPECT_NE(message(compressed_block(2, 0.1, 2, 10, { { "growth", 0.5 } })).find("time.adaptive.growth"),
        std::string::npos);
    EXPECT_NE(message(compressed_block(2, 0.1, 2, 10, { { "min_increment", 2.0 } })).find("time.adaptive.min_increment"),
        std::string::npos);
    EXPECT_NE(message(compressed_block(2, 0.1, 2, 10, { { "cuts", 2 } })).find("time.adaptive.cuts"), std::string::npos);
    EXPECT_NE(message(compressed_block(2, 0.1, 2, 10, { { "displacement_control", 1 } }))
                  .find("time.adaptive.displacement_control"),
        std::string::npos);
    EXPECT_NE(message(compressed_block(2, 0.1, 2, 10, { { "relaxation", "on" } })).find("time.adaptive.relaxation"),
        std::string::npos);
}

namespace {

/// The 2D block of compressed_block() standing on a frictional floor instead of being fixed there,
/// its top face pushed down by 60% and sideways by 30% of its height in `steps` static steps.
json sheared_block_on_floor(int steps, int max_iterations, const json& adaptive = nullptr)
{
    json s = compressed_block(2, 0.6, steps, max_iterations, adaptive);
    s["dirichlet"] = { s["dirichlet"][1] };
    s["dirichlet"][0]["displacement"] = { "0.3*t", "-0.6*t" };
    s["obstacles"] = { { { "name", "floor" }, { "plane", { { "point", { 0, -0.002 } }, { "normal", { 0, 1 } } } } } };
    s["contact"] = { { "dhat", 0.01 }, { "kappa", 1e5 } };
    s["friction"] = { { "coefficient", 0.3 }, { "eps_v", 1e-3 }, { "iterations", 8 } };
    return s;
}

} // namespace

TEST(LoadStepping, WithFrictionSubstepsSlideFromTheirOwnStart)
{
    // Friction depends on the sliding over the solve's increment: each sub-step slides from its own
    // start, and the step's state is its last sub-step's, as a run of those smaller steps would
    // have it (the adjoint refuses such steps: tests/adjoint/test_adjoint.cpp). A lagging re-solve
    // that fails fails the step too, which is then sub-stepped.
    // Without the option the steps commit with their lagging unconverged (the permissive policy):
    // the first solve lags the normal forces at the start, where the block barely touches the
    // floor, so it slides far; the re-solves fail within 12 iterations.
    Simulator plain(test::make_scene(sheared_block_on_floor(2, 12)));
    const Trajectory& unlagged = plain.run();
    ASSERT_EQ(unlagged.final_status, StepStatus::CONVERGED) << unlagged.failure_message;
    EXPECT_GT(std::max(unlagged.step(1).friction_residual, unlagged.step(2).friction_residual), 1e-3);
    Simulator adaptive(test::make_scene(sheared_block_on_floor(2, 12, true)));
    const Trajectory& tr = adaptive.run();
    ASSERT_EQ(tr.final_status, StepStatus::CONVERGED) << tr.failure_message;
    ASSERT_GT(tr.totals.substepped_steps, 0) << "no step was sub-stepped: the check would be plain";
    // Against 64 plain steps with unlimited iterations: the sliding path is resolved more finely
    // there, so the states agree to the path's discretization, not to round-off.
    Simulator fine(test::make_scene(sheared_block_on_floor(64, 200)));
    const Trajectory& ref = fine.run();
    ASSERT_EQ(ref.final_status, StepStatus::CONVERGED) << ref.failure_message;
    const VectorXd& X0 = tr.initial_positions;
    for (int k : { 1, 2 }) {
        SCOPED_TRACE(k);
        const StepRecord& r = tr.step(k);
        EXPECT_LE(r.residual, adaptive.scene().solver.residual_tolerance);
        EXPECT_LE(r.friction_residual, 1e-6);
        const VectorXd& y = ref.step(32 * k).positions;
        EXPECT_LE((r.positions - y).lpNorm<Eigen::Infinity>(), 0.02); // 2% of the block's height
        const Positions X = unflatten(r.positions, 2);
        EXPECT_EQ(count_inverted_elements(adaptive.mesh(), X), 0);
        EXPECT_EQ(find_intersection(adaptive.contact()->collision_mesh(), X, /*all_pairs=*/true), "");
        // Friction acted: the bottom slid sideways, less than the top (0.15 per step), as in the reference.
        double slid = 0, slid_ref = 0;
        for (Index v = 0; v < 25; ++v)
            if (X0[2 * v + 1] < 1e-9) {
                slid = std::max(slid, r.positions[2 * v] - X0[2 * v]);
                slid_ref = std::max(slid_ref, y[2 * v] - X0[2 * v]);
            }
        EXPECT_GT(slid, 0);
        EXPECT_LT(slid, 0.15 * k);
        EXPECT_NEAR(slid, slid_ref, 0.1 * slid_ref);
    }
}
