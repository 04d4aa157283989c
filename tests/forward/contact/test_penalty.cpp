// The penalty contact baseline (contact.model "penalty", forward/contact/penalty.hpp): its
// derivatives against finite differences for every contact kind (including a vertex behind a
// plane, where the penalty stays finite); a resting block whose penalty forces, computed here
// from the positions alone, carry its weight; the baseline's known failure, a fast body passing
// through a thin wall (no CCD), found by the exact intersection test where IPC keeps the bodies
// apart; and the scene keys' errors.

#include "../potential_fd.hpp"
#include "contact_scenes.hpp"

#include "forward/common/error.hpp"
#include "forward/contact/contact_potential.hpp"
#include "forward/contact/intersection.hpp"
#include "forward/contact/penalty.hpp"
#include "forward/simulation/simulator.hpp"

#include <gtest/gtest.h>

using namespace diffipc;
using nlohmann::json;

namespace {

void expect_derivatives(const Simulator& sim, const VectorXd& x, double h)
{
    const test::PotentialFD e = test::potential_fd(*sim.contact(), sim.mesh(), sim.scene().dim, x, h);
    const size_t count = sim.contact()->contacts(x).size();
    std::printf("  %zu contacts, |g| = %.3e, relative errors: gradient %.2e, Hessian %.2e\n", count, e.gradient_norm,
        e.gradient, e.hessian);
    EXPECT_GT(count, 3u);
    EXPECT_GT(e.gradient_norm, 0);
    EXPECT_LT(e.gradient, 1e-6);
    EXPECT_LT(e.hessian, 1e-5);
}

} // namespace

TEST(PenaltyContact, ScalarFormMatchesTheSpringInTheLayer)
{
    const double dhat = 2e-3;
    for (double d : { 1e-4, 1e-3, 1.9e-3 }) {
        const PenaltyValue p = penalty_of_squared_distance(d * d, dhat);
        EXPECT_DOUBLE_EQ(p.value, 0.5 * (dhat - d) * (dhat - d));
        // dP/dd = 2 d dP/ds = -(dhat - d): a spring of unit stiffness.
        EXPECT_NEAR(2 * d * p.first, -(dhat - d), 1e-15);
        const double h = 1e-6 * d * d;
        const PenaltyValue a = penalty_of_squared_distance(d * d + h, dhat),
                           b = penalty_of_squared_distance(d * d - h, dhat);
        EXPECT_NEAR((a.value - b.value) / (2 * h), p.first, 1e-7 * std::abs(p.first));
        EXPECT_NEAR((a.first - b.first) / (2 * h), p.second, 1e-6 * p.second);
        EXPECT_DOUBLE_EQ(penalty_force(d, dhat), dhat - d);
    }
    EXPECT_EQ(penalty_of_squared_distance(dhat * dhat, dhat).value, 0.0);
    EXPECT_EQ(penalty_of_squared_distance(4 * dhat * dhat, dhat).first, 0.0);
    EXPECT_EQ(penalty_force(3 * dhat, dhat), 0.0);
    // Touching surfaces: finite, the full layer's energy (at the clamped distance 1e-9 dhat).
    EXPECT_DOUBLE_EQ(penalty_of_squared_distance(0.0, dhat).value, 0.5 * std::pow(dhat - 1e-9 * dhat, 2));
}

TEST(PenaltyContact, GradientAndHessian2DRingsAndPlane)
{
    Simulator sim(test::make_scene(
        test::rings_on_plane({ { "dhat", 1e-3 }, { "model", "penalty" }, { "penalty_stiffness", 1e4 } })));
    EXPECT_TRUE(sim.contact()->penalty());
    VectorXd x = sim.positions() + 1e-5 * test::random_vector(sim.positions().size(), 7);
    expect_derivatives(sim, x, 1e-9);
    // Sink both rings 0.8 mm: the lowest vertices lie behind the plane, the penalty stays finite.
    for (Index v = 0; v < sim.scene().body_vertices; ++v)
        x[v * 2 + 1] -= 8e-4;
    int behind = 0;
    for (Index v = 0; v < sim.scene().body_vertices; ++v)
        behind += x[v * 2 + 1] < 0;
    EXPECT_GT(behind, 0);
    EXPECT_TRUE(std::isfinite(sim.contact()->value(x)));
    expect_derivatives(sim, x, 1e-9);
}

TEST(PenaltyContact, GradientAndHessian3DBoxesAndPlane)
{
    Simulator sim(test::make_scene(
        test::boxes_on_plane({ { "dhat", 1e-3 }, { "model", "penalty" }, { "penalty_stiffness", 1e4 } })));
    VectorXd x = test::turn_upper_box(sim, 0.3);
    x += 5e-5 * test::random_vector(x.size(), 11);
    int kinds[4] = { 0, 0, 0, 0 };
    for (const Contact& c : sim.contact()->contacts(x))
        ++kinds[int(c.kind)];
    EXPECT_GT(kinds[int(ContactKind::VERTEX_FACE)], 0);
    EXPECT_GT(kinds[int(ContactKind::EDGE_EDGE)], 0);
    EXPECT_GT(kinds[int(ContactKind::VERTEX_PLANE)], 0);
    expect_derivatives(sim, x, 1e-9);
}

TEST(PenaltyContact, RestingBlockCarriesItsWeight)
{
    // A block held sideways at its left edge rests on a plane under gravity (static). At equilibrium
    // the penalty springs k (dhat - h) of the vertices in the layer, computed here from the final
    // positions, sum to the weight rho g |block|.
    const double k = 1e6, dhat = 2e-3, rho = 1000, g = 9.81, W = 1.0, H = 0.2;
    json s = test::box_scene(2, { W, H }, { 8, 2 }, "neo_hookean", 1e6, 0.3, rho);
    s["bodies"][0]["translation"] = { 0.0, 1e-3 };
    s["gravity"] = { 0.0, -g };
    s["obstacles"] = { { { "plane", { { "point", { 0, 0 } }, { "normal", { 0, 1 } } } } } };
    s["contact"] = { { "dhat", dhat }, { "model", "penalty" }, { "penalty_stiffness", k } };
    s["dirichlet"]
        = { { { "body", 0 }, { "region", test::region({ -1, -1 }, { 0, 1 }) }, { "displacement", { 0, nullptr } } } };
    s["time"] = { { "integrator", "static" }, { "dt", 1.0 }, { "steps", 1 } };
    Simulator sim(test::make_scene(s));
    sim.run();
    ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << sim.trajectory().failure_message;
    const VectorXd& x = sim.positions();
    double carried = 0;
    int in_layer = 0;
    for (Index v = 0; v < sim.scene().body_vertices; ++v)
        if (x[v * 2 + 1] < dhat) {
            carried += k * (dhat - x[v * 2 + 1]);
            ++in_layer;
        }
    EXPECT_EQ(in_layer, 9); // the bottom row
    EXPECT_NEAR(carried, rho * g * W * H, 1e-6 * rho * g * W * H);
    // The penetration into the layer is about the weight over 9 springs.
    EXPECT_GT(dhat - x[1], 0.5 * rho * g * W * H / (9 * k));
}

TEST(PenaltyContact, AFastBodyPassesThroughAThinWallWithoutCCD)
{
    // A block at 20 m/s against a 2 cm wall held in place, dt = 10 ms: one step moves it 0.2 m.
    // The penalty (no CCD) never sees the wall; IPC's CCD and barrier stop the block. Every
    // committed state is checked by the exact intersection test, independent of the contact code.
    auto run = [](bool penalty) {
        json s;
        s["dimension"] = 2;
        s["bodies"] = { test::box_body("wall", { 0.0, -0.5 }, { 0.02, 0.5 }, { 1, 20 }),
            test::box_body("block", { -0.2, -0.05 }, { -0.1, 0.05 }, { 2, 2 }) };
        s["bodies"][1]["initial_velocity"] = { 20.0, 0.0 };
        s["bodies"][1]["material"]["E"] = 1e6;
        s["dirichlet"] = { { { "body", "wall" }, { "region", test::region({ -1, -1 }, { 1, 1 }) },
            { "displacement", { 0, 0 } } } };
        s["contact"] = penalty ? json { { "dhat", 1e-3 }, { "model", "penalty" }, { "penalty_stiffness", 1e5 } }
                               : json { { "dhat", 1e-3 } };
        s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", 3 } };
        Simulator sim(test::make_scene(s));
        sim.run();
        int intersecting = 0;
        for (const StepRecord& r : sim.trajectory().steps)
            intersecting
                += !find_intersection(sim.contact()->collision_mesh(), unflatten(r.positions, 2), false).empty();
        double front = -1e30; // the block's rightmost point at the end
        for (Index v = 0; v < sim.scene().body_vertices; ++v)
            if (sim.mesh().vertex_body[v] == 1)
                front = std::max(front, sim.positions()[v * 2]);
        return std::make_tuple(sim.trajectory().final_status, sim.steps_done(), intersecting, front);
    };
    const auto [ipc_status, ipc_steps, ipc_hits, ipc_front] = run(false);
    EXPECT_EQ(ipc_status, StepStatus::CONVERGED);
    EXPECT_EQ(ipc_steps, 3);
    EXPECT_EQ(ipc_hits, 0);
    EXPECT_LT(ipc_front, 0.0);
    const auto [pen_status, pen_steps, pen_hits, pen_front] = run(true);
    EXPECT_EQ(pen_status, StepStatus::CONVERGED);
    // Through the wall: an intersecting committed state, or past it.
    EXPECT_TRUE(pen_hits > 0 || pen_front > 0.02) << pen_hits << " " << pen_front;
    std::printf("  IPC: front %.4f m, 0 intersecting states; penalty: front %.4f m, %d intersecting states\n",
        ipc_front, pen_front, pen_hits);
}

TEST(PenaltyContact, SceneKeysAreChecked)
{
    json s = test::box_scene(2, { 1.0, 0.2 }, { 2, 1 });
    s["obstacles"] = { { { "plane", { { "point", { 0, -0.1 } }, { "normal", { 0, 1 } } } } } };
    auto error = [&](const json& contact) {
        json t = s;
        t["contact"] = contact;
        try {
            test::make_scene(t);
        } catch (const InputError& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    EXPECT_NE(error({ { "model", "penalty" } }).find("penalty_stiffness"), std::string::npos);
    EXPECT_NE(error({ { "model", "penalty" }, { "penalty_stiffness", 1e5 }, { "kappa", 1.0 } }).find("contact.kappa"),
        std::string::npos);
    EXPECT_NE(error({ { "model", "penalty" }, { "penalty_stiffness", -1.0 } }).find("contact.penalty_stiffness"),
        std::string::npos);
    EXPECT_NE(error({ { "penalty_stiffness", 1e5 } }).find("contact.penalty_stiffness"), std::string::npos);
    EXPECT_NE(error({ { "model", "barrier" } }).find("contact.model"), std::string::npos);
    EXPECT_NE(error({ { "model", "penalty" }, { "penalty_stiffness", 1e5 }, { "ccd_rescaling", 0.5 } })
                  .find("contact.ccd_rescaling"),
        std::string::npos);
    EXPECT_NE(error({ { "model", "penalty" }, { "penalty_stiffness", 1e5 }, { "min_distance", 1e-4 } })
                  .find("contact.min_distance"),
        std::string::npos);
    EXPECT_EQ(error({ { "model", "penalty" }, { "penalty_stiffness", 1e5 } }), "");
    EXPECT_EQ(error({ { "model", "ipc" } }), "");
}
