#include "objectives/reaction_force.hpp"
#include "objectives/state_tracking.hpp"

#include "adjoint/adjoint_check.hpp"
#include "objective_fd.hpp"
#include "objectives/objective_json.hpp"
#include "objectives/time_aggregation.hpp"
#include "through_adjoint.hpp"

using namespace diffipc;
using json = nlohmann::json;
using test::Block;
using test::block_name;
using test::block_vector;

namespace {

/// A block [0, W] x [0, H] (x [0, D]) on rollers: its bottom held along y, its left side
/// along x (and its back along z), its top pushed down by `delta` along y in one static step.
/// Linear elasticity has the uniform solution sigma_yy = E' delta / H, every other stress zero,
/// with E' = E / (1 - nu^2) in plane strain and E in 3D; P1 elements reproduce it exactly.
json rollers(int dim, double delta)
{
    const bool three = dim == 3;
    json s = three ? test::box_scene(3, { 0.3, 0.2, 0.1 }, { 3, 2, 1 }, "linear", 1e5, 0.3, 1000)
                   : test::box_scene(2, { 0.3, 0.2 }, { 3, 2 }, "linear", 1e5, 0.3, 1000);
    const auto box = [&](double x0, double x1, double y0, double y1, double z0, double z1) {
        return three ? test::region({ x0, y0, z0 }, { x1, y1, z1 }) : test::region({ x0, y0 }, { x1, y1 });
    };
    const auto along = [&](int axis, const json& value) {
        json d = three ? json { nullptr, nullptr, nullptr } : json { nullptr, nullptr };
        d[size_t(axis)] = value;
        return d;
    };
    s["dirichlet"] = { { { "body", 0 }, { "region", box(-1, 1, -1, 1e-6, -1, 1) }, { "displacement", along(1, 0) } },
        { { "body", 0 }, { "region", box(-1, 1e-6, -1, 1, -1, 1) }, { "displacement", along(0, 0) } },
        { { "body", 0 }, { "region", box(-1, 1, 0.2 - 1e-6, 1, -1, 1) },
            { "displacement", along(1, std::to_string(delta) + "*t") } } };
    if (three)
        s["dirichlet"].push_back(
            { { "body", 0 }, { "region", box(-1, 1, -1, 1, -1, 1e-6) }, { "displacement", along(2, 0) } });
    s["time"] = { { "integrator", "static" }, { "dt", 1.0 }, { "steps", 1 } };
    return s;
}

double final_force(const Simulator& sim, int condition, int axis)
{
    const ReactionForce f(prescribed_dofs_of(sim, condition, axis), "test");
    const Trajectory& tr = sim.trajectory();
    const int T = num_steps(tr);
    return f.value(sim, { T, state_time(tr, T), state_positions(tr, T), state_velocities(tr, T) });
}

TEST(ReactionForce, UniaxialCompressionMatchesElasticity)
{
    for (int dim : { 2, 3 }) {
        const double delta = -0.004, E = 1e5, nu = 0.3;
        Simulator sim(test::make_scene(rollers(dim, delta)));
        sim.run();
        ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED);
        const double modulus = dim == 2 ? E / (1 - nu * nu) : E;
        const double area = dim == 2 ? 0.3 : 0.3 * 0.1;
        const double expected = modulus * delta / 0.2 * area; // negative: the top plate pushes down
        EXPECT_NEAR(final_force(sim, 2, 1), expected, 1e-8 * std::abs(expected)) << dim;
        EXPECT_NEAR(final_force(sim, 0, 1), -expected, 1e-8 * std::abs(expected)) << dim;
        // The side rollers carry no load in the uniform state.
        EXPECT_NEAR(final_force(sim, 1, 0), 0, 1e-8 * std::abs(expected)) << dim;
    }
}

/// box_over_rising_plane, static: the box's top is clamped while the rising plane presses it
/// from below against a strong gravity (as the adjoint's contact tests).
json clamped_box_on_plane(int dim)
{
    const double dhat = 2e-3;
    json s = test::box_over_rising_plane(dim, "static", dhat, 0.01, 3);
    s["bodies"][0]["translation"] = dim == 2 ? json { 0, 0.5 * dhat } : json { 0, 0.5 * dhat, 0 };
    s["gravity"] = dim == 2 ? json { 0, -20 } : json { 0, -20, 0 };
    // A stiff barrier keeps the gaps at a fair fraction of dhat (with kappa = 1e3 they close to
    // below 1e-6 m, where a finite difference of 1e-6 m crosses the plane).
    s["contact"]["kappa"] = 1e8;
    s["obstacles"][0]["plane"]["motion"] = dim == 2 ? json { 0, "0.02*t" } : json { 0, "0.02*t", 0 };
    const double top = 0.1 + 0.5 * dhat - 1e-6;
    s["dirichlet"] = { { { "body", "body" },
        { "region", dim == 2 ? test::region({ -1, top }, { 1, 1 }) : test::region({ -1, top, -1 }, { 1, 1, 1 }) },
        { "displacement", dim == 2 ? json { 0, 0 } : json { 0, 0, 0 } } } };
    return s;
}

TEST(ReactionForce, SupportsCarryTheWeight)
{
    // Sum over all dofs of grad Psi and grad B vanishes (translation invariance), and the free
    // rows balance: so the reactions of all the supports add up to minus the applied load.
    for (int dim : { 2, 3 }) {
        Simulator sim(test::make_scene(clamped_box_on_plane(dim)));
        sim.run();
        ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED);
        ASSERT_GT(sim.trajectory().steps.back().active_contacts, 0);
        const double volume = dim == 2 ? 0.2 * 0.1 : 0.2 * 0.1 * 0.2;
        const double weight = 1000 * volume * 20;
        const double top = final_force(sim, 0, 1), floor = final_force(sim, 1, 1);
        EXPECT_GT(floor, 0.2 * weight) << dim << ": the plane must carry part of the load";
        EXPECT_NEAR(top + floor, weight, 1e-6 * weight) << dim;
        EXPECT_NEAR(final_force(sim, 0, 0) + final_force(sim, 1, 0), 0, 1e-6 * weight) << dim;
    }
}

class ReactionForceGradient : public ::testing::TestWithParam<int> { };

TEST_P(ReactionForceGradient, MatchesFiniteDifferences)
{
    // The cantilever: clamped at x = 0 (condition 0) under gravity and a traction. The
    // functional is evaluated on (randomly displaced) states, not only at equilibria.
    const test::Run run = test::run_scene(test::cantilever_scene(GetParam()));
    for (int axis = 0; axis < 2; ++axis) {
        SCOPED_TRACE(axis);
        const TimeAggregation J(
            std::make_unique<ReactionForce>(prescribed_dofs_of(*run.sim, 0, axis), "clamp"), TimeMode::SUM, 8, true);
        ASSERT_NE(J.value(*run.sim, run.trajectory), 0);
        test::check_state_gradient(J, run);
        test::check_all_parameter_gradients(J, run);
    }
    const ReactionForce Ry(prescribed_dofs_of(*run.sim, 0, 1), "clamp");
    // Targets away from the forces (R - F of the size of R), so that J's differences do not cancel.
    const auto R = [&](int k) {
        return Ry.value(*run.sim,
            { k, state_time(run.trajectory, k), state_positions(run.trajectory, k),
                state_velocities(run.trajectory, k) });
    };
    const StateTracking tracking(std::make_unique<ReactionForce>(Ry), { 1, 3 }, { 0.5 * R(1), 1.5 * R(3) }, 0.25);
    test::check_state_gradient(tracking, run);
    test::check_all_parameter_gradients(tracking, run);
    // One-sided: R(1) is past its target on one side and R(3) on the other, so each bound keeps
    // exactly one of the two terms, and the two bounds add up to the two-sided J.
    const double r1 = 0.5 * R(1), r3 = -0.5 * R(3); // R - y at states 1 and 3
    ASSERT_LT(r1 * r3, 0) << "the residuals must have opposite signs";
    double both = 0;
    for (TrackingSide side : { TrackingSide::ABOVE, TrackingSide::BELOW }) {
        SCOPED_TRACE(side == TrackingSide::ABOVE ? "above" : "below");
        const StateTracking bound(
            std::make_unique<ReactionForce>(Ry), { 1, 3 }, { 0.5 * R(1), 1.5 * R(3) }, 0.25, side);
        const double kept = (side == TrackingSide::ABOVE) == (r1 > 0) ? r1 : r3;
        EXPECT_NEAR(bound.value(*run.sim, run.trajectory), 0.125 * kept * kept, 1e-12 * kept * kept);
        both += bound.value(*run.sim, run.trajectory);
        test::check_state_gradient(bound, run);
        test::check_all_parameter_gradients(bound, run);
    }
    EXPECT_NEAR(both, tracking.value(*run.sim, run.trajectory), 1e-12 * both);
}

INSTANTIATE_TEST_SUITE_P(Dims, ReactionForceGradient, ::testing::Values(2, 3));

TEST(ReactionForceGradient, ContactMatchesFiniteDifferences)
{
    // The plane's force: the barrier's Hessian. (Its parameter partials vanish: the plane's
    // point has no element, no mass and no edge.)
    for (int dim : { 2, 3 }) {
        test::Run run;
        run.scene_json = clamped_box_on_plane(dim);
        run.sim = std::make_unique<Simulator>(test::make_scene(run.scene_json));
        run.trajectory = run.sim->run();
        ASSERT_EQ(run.trajectory.final_status, StepStatus::CONVERGED);
        ASSERT_GT(run.sim->contact()->min_distance(state_positions(run.trajectory, 3), 1.0), 1e-5);
        const TimeAggregation J(
            std::make_unique<ReactionForce>(prescribed_dofs_of(*run.sim, 1, 1), "floor"), TimeMode::SUM);
        test::check_state_gradient(J, run, 11, 1e-5);
    }
}

TEST(ReactionForceGradient, MollifiedEdgeEdgeContactsMatchFiniteDifferences)
{
    // Two boxes of one footprint, the upper one turned by 1 degree about the vertical and held
    // (every vertex prescribed) 1 mm above the lower one, then lowered: their top and bottom
    // edges are nearly parallel and within dhat, so the edge-edge mollifier is active and the
    // barrier's gradient depends on the rest positions.
    const double dhat = 2e-3;
    json s = test::box_scene(3, { 0.2, 0.1, 0.2 }, { 1, 1, 1 }, "neo_hookean", 2e4, 0.3, 1000);
    s["bodies"] = { test::box_body("below", { 0, 0, 0 }, { 0.2, 0.1, 0.2 }, { 1, 1, 1 }),
        test::box_body("above", { 0, 0.1 + 0.5 * dhat, 0 }, { 0.2, 0.2 + 0.5 * dhat, 0.2 }, { 1, 1, 1 }) };
    s["bodies"][1]["rotation"] = { 0, 1, 0 };
    s["dirichlet"] = { { { "body", "below" }, { "region", test::region({ -1, -1, -1 }, { 1, 1e-6, 1 }) },
                           { "displacement", { 0, 0, 0 } } },
        { { "body", "above" }, { "region", test::region({ -1, -1, -1 }, { 1, 1, 1 }) },
            { "displacement", { 0, "-0.0004*t", 0 } } } };
    s["contact"] = { { "dhat", dhat }, { "kappa", 1e7 } }; // stiff: the gaps stay near dhat / 2
    s["time"] = { { "integrator", "static" }, { "dt", 0.5 }, { "steps", 2 } };
    s["solver"] = { { "residual_tolerance", 1e-11 } };
    test::Run run;
    run.scene_json = s;
    run.sim = std::make_unique<Simulator>(test::make_scene(s));
    run.trajectory = run.sim->run();
    ASSERT_EQ(run.trajectory.final_status, StepStatus::CONVERGED) << run.trajectory.failure_message;
    const std::vector<Index> dofs = prescribed_dofs_of(*run.sim, 1, 1);
    ASSERT_FALSE(dofs.empty());
    ASSERT_GT(run.sim->contact()->min_distance(state_positions(run.trajectory, 2), 1.0), 1e-4);
    // The check is only meaningful if the barrier's shape derivative along s is not zero.
    VectorXd s_vector = VectorXd::Zero(run.sim->mesh().num_dofs()), d_rest = s_vector;
    for (const Index i : dofs)
        s_vector[i] = 1;
    run.sim->contact()->add_shape_derivative(state_positions(run.trajectory, 2), s_vector, 1.0, d_rest);
    ASSERT_GT(d_rest.norm(), 0) << "no mollified edge-edge contact: the check would be empty";
    const TimeAggregation J(std::make_unique<ReactionForce>(dofs, "above"), TimeMode::SUM);
    ASSERT_GT(std::abs(J.value(*run.sim, run.trajectory)), 0);
    test::check_state_gradient(J, run, 11, 1e-5);
    test::check_parameter_gradient(J, run, Block::REST_POSITIONS, 23, 1e-5);
}

TEST(ReactionForceAdjoint, StaticCompressionMatchesFiniteDifferences)
{
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE(dim);
        json s = rollers(dim, -0.01);
        s["bodies"][0]["material"]["model"] = "neo_hookean";
        s["gravity"] = dim == 2 ? json { 0, -50 } : json { 0, -50, 0 };
        s["time"] = { { "integrator", "static" }, { "dt", 0.5 }, { "steps", 2 } };
        const json objective = { { "type", "reaction_force" }, { "dirichlet", 2 }, { "axis", "y" },
            { "targets", { -100.0, -250.0 } }, { "sigma", 10.0 } };
        test::check_through_adjoint(s, objective,
            { Block::REST_POSITIONS, Block::MU, Block::LAMBDA, Block::DENSITY, Block::PRESCRIBED }, 1e-2, 1e-6);
    }
}

TEST(ReactionForceAdjoint, PlaneContactMatchesFiniteDifferences)
{
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE(dim);
        const json objective
            = { { "type", "reaction_force" }, { "obstacle", "floor" }, { "axis", 1 }, { "time", "sum" } };
        test::check_through_adjoint(clamped_box_on_plane(dim), objective,
            { Block::REST_POSITIONS, Block::MU, Block::LAMBDA, Block::PRESCRIBED }, 1e-3, 1e-5);
    }
}

TEST(ReactionForceJson, ErrorsNameTheField)
{
    Simulator sim(test::make_scene(rollers(2, -0.004)));
    const auto message = [&](const json& j) { return test::objective_error(j, sim); };
    const json base = { { "type", "reaction_force" }, { "dirichlet", 2 }, { "axis", "y" } };
    EXPECT_EQ(message(base), "no error");
    json j = base;
    j["obstacle"] = 0;
    EXPECT_NE(message(j).find("exactly one of"), std::string::npos) << message(j);
    j = base;
    j["dirichlet"] = 3;
    EXPECT_NE(message(j).find("objective.dirichlet"), std::string::npos) << message(j);
    j = base;
    j["axis"] = "z";
    EXPECT_NE(message(j).find("objective.axis"), std::string::npos) << message(j);
    j = base;
    j["axis"] = "x"; // the top condition prescribes y only
    EXPECT_NE(message(j).find("prescribes no dof along axis 0"), std::string::npos) << message(j);
    j = base;
    j["steps"] = { 1 };
    EXPECT_NE(message(j).find("objective.steps: only applies with \"targets\""), std::string::npos) << message(j);
    j = base;
    j["targets"] = { 1.0, 2.0 };
    EXPECT_NE(message(j).find("objective.targets"), std::string::npos) << message(j);
    j = base;
    j["side"] = "above";
    EXPECT_NE(message(j).find("objective.side: only applies with \"targets\""), std::string::npos) << message(j);
    j = base;
    j["targets"] = { 1.0 };
    j["steps"] = { 1 };
    j["side"] = "up";
    EXPECT_NE(message(j).find("objective.side"), std::string::npos) << message(j);
    j["side"] = "below";
    EXPECT_EQ(message(j), "no error");
    j = base;
    j["obstacle"] = "plate";
    j.erase("dirichlet");
    EXPECT_NE(message(j).find("objective.obstacle"), std::string::npos) << message(j);

    json friction = clamped_box_on_plane(2);
    friction["friction"] = { { "coefficient", 0.3 } };
    Simulator with_friction(test::make_scene(friction));
    try {
        parse_objective(base, "objective", with_friction);
        ADD_FAILURE() << "a scene with friction must be refused";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("friction"), std::string::npos) << e.what();
    }
}

} // namespace
