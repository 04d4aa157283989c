// The force holding up a falling block (objectives/body_force.hpp): under implicit Euler it equals
// the contact force the barrier puts on the block (independent of the momentum it is computed
// from), its state and explicit gradients against central differences, and its gradient through
// the adjoint of the drop against whole runs, for the final force and its smooth maximum, with and
// without friction.

#include "objectives/body_force.hpp"

#include "objective_fd.hpp"
#include "objectives/objective_json.hpp"
#include "through_adjoint.hpp"

using namespace diffipc;
using json = nlohmann::json;
using test::Block;

namespace {

/// A block (0.2 x 0.05 m) falling at 0.5 m/s onto a pad (0.6 x 0.1 m, its bottom held) 5 mm below,
/// implicit Euler, contact with a fixed stiffness, no friction.
json drop_scene(int steps)
{
    json s;
    s["dimension"] = 2;
    s["bodies"] = {
        { { "name", "pad" },
            { "mesh", { { "box", { { "min", { 0, 0 } }, { "max", { 0.6, 0.1 } }, { "cells", { 12, 2 } } } } } },
            { "material", { { "model", "neo_hookean" }, { "E", 1e5 }, { "nu", 0.3 }, { "density", 500 } } } },
        { { "name", "block" },
            { "mesh", { { "box", { { "min", { 0.2, 0.105 } }, { "max", { 0.4, 0.155 } }, { "cells", { 4, 1 } } } } } },
            { "material", { { "model", "neo_hookean" }, { "E", 1e6 }, { "nu", 0.3 }, { "density", 2000 } } },
            { "initial_velocity", { 0, -0.5 } } }
    };
    s["dirichlet"]
        = { { { "body", 0 }, { "region", test::region({ -1, -1 }, { 2, 1e-6 }) }, { "displacement", { 0, 0 } } } };
    s["gravity"] = { 0, -9.81 };
    s["contact"] = { { "dhat", 2e-3 }, { "kappa", 1e5 } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.005 }, { "steps", steps } };
    s["solver"] = { { "residual_tolerance", 1e-11 }, { "max_iterations", 400 } };
    return s;
}

} // namespace

TEST(BodyForce, UnderImplicitEulerItIsTheContactForceOnTheBlock)
{
    for (int steps : { 2, 5, 8 }) {
        SCOPED_TRACE(steps);
        const test::Run run = test::run_cell(drop_scene(steps));
        const BodyForce F(1, 1, TimeMode::FINAL);
        const VectorXd c = run.sim->contact_forces();
        double contact = 0;
        for (Index v = 0; v < run.sim->mesh().num_vertices(); ++v)
            if (run.sim->mesh().vertex_body[v] == 1)
                contact += c[2 * v + 1];
        const double f = F.value(*run.sim, run.trajectory);
        EXPECT_NEAR(f, contact, 1e-6 * std::max(std::abs(contact), 1e-3)) << "momentum " << f << " contact " << contact;
        if (steps == 8)
            EXPECT_GT(contact, 1.0); // the block is held up by then
    }
}

TEST(BodyForce, GradientsMatchDifferencesAndWholeRuns)
{
    const json scene = drop_scene(8);
    const test::Run run = test::run_cell(scene);
    for (TimeMode mode : { TimeMode::FINAL, TimeMode::MAX_P }) {
        SCOPED_TRACE(to_string(mode));
        const BodyForce F(1, 1, mode, 6);
        // max_p: d/dv_1 moves the first contact's small force, whose sixth power the central
        // difference (h = 1e-6) resolves to 1.5e-5 only (its truncation; the rest agree to 1e-9)
        test::check_state_gradient(F, run, 11, mode == TimeMode::MAX_P ? 1e-4 : 1e-6);
        test::check_parameter_gradient(F, run, Block::REST_POSITIONS, 19, 1e-6);
        test::check_parameter_gradient(F, run, Block::DENSITY, 29, 1e-6);
    }
    const json final_force = { { "type", "body_force" }, { "body", "block" }, { "axis", "y" } };
    const json peak
        = { { "type", "body_force" }, { "body", "block" }, { "axis", "y" }, { "time", { { "max_p", 6 } } } };
    for (const json& objective : { final_force, peak }) {
        SCOPED_TRACE(objective.dump());
        test::check_through_adjoint(scene, objective,
            { Block::REST_POSITIONS, Block::MU, Block::LAMBDA, Block::DENSITY, Block::INITIAL_VELOCITY }, 1e-5, 1e-5);
    }
    // With friction: the block also slides (2 cm/s along x), mu = 0.3, eps_v = 1 cm/s. (At 0.2
    // m/s the forward solve stalls at the first contact with this scene's fixed kappa 1e5, far
    // below the adaptive rule's minimum 2.4e9; from about 1e7 on it runs: test_extreme.cpp.)
    json sliding = scene;
    sliding["bodies"][1]["initial_velocity"] = { 0.02, -0.5 };
    sliding["friction"] = { { "coefficient", 0.3 }, { "eps_v", 0.01 } };
    // Difference step 1e-4: the sliding runs' convergence noise (residual 1e-11) moves J by about
    // 1e-10 J between runs, which a step of 1e-5 turns into errors of 5e-6 .. 1.4e-5 on d/dmu (and
    // 1.6e-4 at 1e-6); at 1e-4 the truncation is below 1e-6 (measured on this scene, 2026-11-28).
    test::check_through_adjoint(
        sliding, peak, { Block::REST_POSITIONS, Block::DENSITY, Block::INITIAL_VELOCITY, Block::FRICTION }, 1e-4, 1e-5);
}

TEST(BodyForce, ProblemFileErrorsNameTheField)
{
    Simulator sim(test::make_scene(drop_scene(1)));
    const auto message = [&](const json& j) { return test::objective_error(j, sim); };
    EXPECT_EQ(message({ { "type", "body_force" }, { "body", "block" }, { "axis", "y" } }), "no error");
    EXPECT_EQ(message({ { "type", "body_force" }, { "axis", "y" } }), "objective: body_force needs \"body\"");
    EXPECT_EQ(message({ { "type", "body_force" }, { "body", "block" }, { "axis", "z" } }),
        "objective.axis: expected x or y, got \"z\"");
    EXPECT_EQ(message({ { "type", "body_force" }, { "body", "lid" }, { "axis", "y" } }),
        "objective.body: no body named \"lid\"");
    EXPECT_EQ(message({ { "type", "body_force" }, { "body", "block" }, { "axis", "y" }, { "time", "trapezoid" } }),
        "objective.time: body_force takes final, sum or {\"max_p\": p}");
}
