// Simulator::contact_forces() and friction_forces() (written to the VTU frames): nodal forces
// in newtons, checked against the weight of a body at rest, m g from its density and volume.

#include "forward/simulation/simulator.hpp"
#include "tests/forward/test_utils.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

using namespace diffipc;

namespace {

constexpr double G = 9.81, DENSITY = 1000;

/// A 0.1 x 0.05 (x 0.05) block, neo-Hookean E = 1e6, resting 1e-4 above a plane through
/// the origin whose normal is tilted by `degrees` about z; gravity -g y.
nlohmann::json block_on_plane(int dim, double degrees, double mu, const std::string& integrator, int steps)
{
    const double a = degrees * M_PI / 180;
    std::vector<double> hi = { 0.1, 0.0501 }, lo = { 0.0, 1e-4 }, normal = { -std::sin(a), std::cos(a) };
    std::vector<int> cells = { 4, 2 };
    nlohmann::json s = test::box_scene(dim, hi, cells, "neo_hookean", 1e6, 0.3, DENSITY);
    if (dim == 3) {
        hi.push_back(0.05), lo.push_back(0.0), normal.push_back(0.0), cells.push_back(2);
        s = test::box_scene(dim, hi, cells, "neo_hookean", 1e6, 0.3, DENSITY);
    }
    s["bodies"][0]["mesh"]["box"]["min"] = lo;
    s["bodies"][0]["rotation"] = dim == 2 ? nlohmann::json { degrees } : nlohmann::json { 0, 0, degrees };
    s["obstacles"] = { { { "name", "ground" },
        { "plane", { { "point", std::vector<double>(size_t(dim), 0.0) }, { "normal", normal } } } } };
    s["contact"] = { { "dhat", 2e-4 } };
    if (mu > 0)
        s["friction"] = { { "coefficient", mu }, { "eps_v", 1e-3 }, { "iterations", 3 } };
    std::vector<double> gravity(size_t(dim), 0.0);
    gravity[1] = -G;
    s["gravity"] = gravity;
    s["time"] = { { "integrator", integrator }, { "dt", 0.01 }, { "steps", steps } };
    return s;
}

/// Sum over the body vertices [0, nb) of flattened forces, as a 3-vector.
Eigen::Vector3d body_sum(const VectorXd& f, Index nb, int dim)
{
    Eigen::Vector3d s = Eigen::Vector3d::Zero();
    for (Index v = 0; v < nb; ++v)
        s.head(dim) += f.segment(v * dim, dim);
    return s;
}

void run(Simulator& sim)
{
    while (sim.steps_done() < sim.scene().time.steps)
        ASSERT_EQ(sim.step(), StepStatus::CONVERGED) << sim.trajectory().failure_message;
}

} // namespace

TEST(ContactForces, BodyAtRestOnAPlaneWeighsMG)
{
    for (int dim : { 2, 3 })
        for (const char* integrator : { "static", "implicit_euler" }) {
            Simulator sim(test::make_scene(block_on_plane(dim, 0, 0, integrator, integrator[0] == 's' ? 1 : 100)));
            run(sim);
            const double weight = DENSITY * 0.1 * 0.05 * (dim == 3 ? 0.05 : 1.0) * G;
            const Index nb = sim.scene().body_vertices;
            const VectorXd f = sim.contact_forces();
            const Eigen::Vector3d total = body_sum(f, nb, dim);
            // Static: equilibrium to the residual tolerance. Implicit Euler after 1 s: the block
            // has settled (its bounce is damped by the scheme), the inertia left is below 1e-6 m g.
            EXPECT_NEAR(total[1], weight, 1e-6 * weight) << dim << "D " << integrator;
            EXPECT_NEAR(total[0], 0, 1e-6 * weight);
            EXPECT_NEAR(total[2], 0, 1e-6 * weight);
            // Only the bottom vertices touch; the plane's point carries the reaction.
            for (Index v = 0; v < nb; ++v)
                if (sim.positions()[v * dim + 1] > 0.01)
                    EXPECT_EQ(f.segment(v * dim, dim).norm(), 0.0) << "vertex " << v;
            const Index plane = sim.scene().obstacles[0].first_vertex;
            EXPECT_NEAR(f[plane * dim + 1], -weight, 1e-6 * weight);
            EXPECT_EQ(sim.friction_forces().norm(), 0.0);
            EXPECT_EQ(sim.friction(), nullptr);
        }
}

// A block on a 20 degree slope with mu = 0.5 > tan 20 = 0.36 sticks. Smoothed Coulomb friction
// holds it by creep: its slip speed stays below eps_v (f1(y) = tan(theta) / mu = 0.73 < 1 puts
// it at y = 0.48 eps_v h per step), at which the friction force is the full m g sin(theta). A
// steady creep has no acceleration, so the balance holds to the residual and the inertia that
// is left after 1 s (below 1e-6 m g), not to the smoothing.
TEST(ContactForces, FrictionHoldsABlockOnASlope)
{
    const double theta = 20 * M_PI / 180, mu = 0.5, eps_v = 1e-3;
    for (const char* integrator : { "static", "implicit_euler" }) {
        Simulator sim(test::make_scene(block_on_plane(2, 20, mu, integrator, integrator[0] == 's' ? 3 : 100)));
        EXPECT_EQ(sim.friction_forces().norm(), 0.0); // no step yet: no friction data
        run(sim);
        const double weight = DENSITY * 0.1 * 0.05 * G;
        const Index nb = sim.scene().body_vertices;
        const Eigen::Vector3d n(-std::sin(theta), std::cos(theta), 0), t(std::cos(theta), std::sin(theta), 0);
        const Eigen::Vector3d contact = body_sum(sim.contact_forces(), nb, 2);
        const Eigen::Vector3d friction = body_sum(sim.friction_forces(), nb, 2);
        EXPECT_NEAR(contact.dot(n), weight * std::cos(theta), 1e-6 * weight) << integrator;
        EXPECT_NEAR(contact.dot(t), 0, 1e-6 * weight);
        EXPECT_NEAR(friction.dot(t), weight * std::sin(theta), 1e-6 * weight) << integrator;
        EXPECT_NEAR(friction.dot(n), 0, 1e-6 * weight);
        EXPECT_LT(friction.norm(), mu * contact.dot(n)); // inside the Coulomb cone: sticking
        double speed = 0;
        for (Index v = 0; v < nb; ++v)
            speed = std::max(speed, sim.velocities().segment(v * 2, 2).norm());
        EXPECT_LT(speed, eps_v) << integrator;
        // The forces are those of the committed state only.
        sim.restore_state(sim.steps_done() - 1);
        EXPECT_EQ(sim.friction_forces().norm(), 0.0);
    }
}

TEST(ContactForces, ObstacleMeshCarriesTheReaction)
{
    // A 2D block resting on an obstacle polyline (y = 0 from x = -1 to 1, two segments).
    const auto dir = std::filesystem::temp_directory_path() / "diffipc_contact_forces";
    std::filesystem::create_directories(dir);
    std::ofstream((dir / "ground.obj").string()) << "v -1 0 0\nv 0.05 0 0\nv 1 0 0\nl 1 2 3\n";
    nlohmann::json s = block_on_plane(2, 0, 0, "static", 1);
    s["obstacles"] = { { { "name", "ground" }, { "mesh", { { "file", "ground.obj" } } } } };
    Simulator sim(parse_scene(s, dir.string(), "<test>"));
    run(sim);
    const double weight = DENSITY * 0.1 * 0.05 * G;
    const VectorXd f = sim.contact_forces();
    const Index nb = sim.scene().body_vertices, nv = sim.mesh().num_vertices();
    EXPECT_NEAR(body_sum(f, nb, 2)[1], weight, 1e-6 * weight);
    double reaction = 0;
    for (Index v = nb; v < nv; ++v)
        reaction += f[v * 2 + 1];
    EXPECT_NEAR(reaction, -weight, 1e-6 * weight);
    std::filesystem::remove_all(dir);
}

TEST(ContactForces, ZeroWithoutContact)
{
    Simulator sim(test::make_scene(test::box_scene(2, { 0.5, 0.2 }, { 4, 2 })));
    run(sim);
    EXPECT_EQ(sim.contact_forces().size(), sim.mesh().num_dofs());
    EXPECT_EQ(sim.contact_forces().norm(), 0.0);
    EXPECT_EQ(sim.friction_forces().norm(), 0.0);
}

TEST(ContactForces, FrictionForcesSurviveForgottenRecords)
{
    // The CLI drops every record once written (forget_records): the forces stay those of the last step.
    Simulator sim(test::make_scene(block_on_plane(2, 20, 0.5, "implicit_euler", 5)));
    run(sim);
    const VectorXd friction = sim.friction_forces(), contact = sim.contact_forces();
    EXPECT_GT(friction.norm(), 0.0);
    sim.forget_records();
    EXPECT_EQ(sim.friction_forces(), friction);
    EXPECT_EQ(sim.contact_forces(), contact);
}
