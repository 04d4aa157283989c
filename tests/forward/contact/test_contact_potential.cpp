// Finite-difference checks of the assembled barrier potential (value ->
// gradient -> true Hessian) at states with active contacts of every kind:
// 2D vertex-edge and vertex-plane, 3D vertex-face, edge-edge (mollified) and
// vertex-plane.

#include "../potential_fd.hpp"

#include "forward/contact/contact_potential.hpp"
#include "forward/simulation/simulator.hpp"
#include "forward/solver/sparse_assembler.hpp"

#include <gtest/gtest.h>

#include <cstdio>

using namespace diffipc;
using nlohmann::json;

namespace {

struct Check {
    double gradient_error, hessian_error;
    int contacts;
    double gradient_norm;
};

Check fd_check(const Simulator& sim, const VectorXd& x)
{
    const int count = int(sim.contact()->contacts(x).size());
    // A small fraction of dhat (1e-3).
    const test::PotentialFD e = test::potential_fd(*sim.contact(), sim.mesh(), sim.scene().dim, x, 1e-7 * 1e-3);
    std::printf("  %d contacts, |g| = %.3e, relative errors: gradient %.2e, Hessian %.2e\n", count, e.gradient_norm,
        e.gradient, e.hessian);
    return { e.gradient, e.hessian, count, e.gradient_norm };
}

/// Moves body vertices of x by a random smooth perturbation, keeping contacts active.
VectorXd jiggle(const VectorXd& x, double amplitude, unsigned seed)
{
    return x + amplitude * test::random_vector(x.size(), seed);
}

} // namespace

TEST(ContactPotential, GradientAndHessian2DRingOnPlaneAndSelf)
{
    // A 2D ring resting within dhat of a plane and of a second ring.
    json s;
    s["dimension"] = 2;
    json ring = { { "mesh",
                      { { "annulus",
                          { { "center", { 0, 0.3 } }, { "inner_radius", 0.2 }, { "outer_radius", 0.2995 },
                              { "segments", 24 }, { "layers", 1 } } } } },
        { "material", { { "model", "neo_hookean" }, { "E", 1e5 }, { "nu", 0.3 }, { "density", 1000 } } } };
    json ring2 = ring;
    ring2["mesh"]["annulus"]["center"] = { 0.5995, 0.3 };
    ring["name"] = "a";
    ring2["name"] = "b";
    s["bodies"] = { ring, ring2 };
    s["obstacles"] = { { { "plane", { { "point", { 0, 0 } }, { "normal", { 0, 1 } } } } } };
    s["contact"] = { { "dhat", 1e-3 }, { "kappa", 1.0 } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", 1 } };
    Simulator sim(test::make_scene(s));
    const VectorXd x = jiggle(sim.positions(), 1e-5, 7);
    const Check c = fd_check(sim, x);
    EXPECT_GT(c.contacts, 3);
    EXPECT_GT(c.gradient_norm, 0);
    EXPECT_LT(c.gradient_error, 1e-5);
    EXPECT_LT(c.hessian_error, 1e-5);
}

TEST(ContactPotential, GradientAndHessian3DBoxesAndPlane)
{
    // Two boxes, the second rotated about y so that edges cross edges, within dhat of each other and of a plane.
    json s;
    s["dimension"] = 3;
    auto box = [](const std::string& name, std::vector<double> lo, std::vector<double> hi) {
        return test::box_body(name, lo, hi, std::vector<int> { 2, 1, 2 });
    };
    s["bodies"] = { box("a", { 0, 0.0005, 0 }, { 1, 0.5, 1 }), box("b", { 0.1, 0.5005, 0.1 }, { 0.9, 1.0, 0.9 }) };
    s["obstacles"] = { { { "plane", { { "point", { 0, 0, 0 } }, { "normal", { 0, 1, 0 } } } } } };
    s["contact"] = { { "dhat", 1e-3 }, { "kappa", 1.0 } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", 1 } };
    Simulator sim(test::make_scene(s));
    // Rotate body b by 0.3 rad about the vertical axis through its centre so edges cross.
    VectorXd x = sim.positions();
    const Index nv = sim.mesh().num_vertices();
    for (Index v = 0; v < sim.scene().body_vertices; ++v) {
        if (sim.mesh().vertex_body[v] != 1)
            continue;
        const double px = x[v * 3] - 0.5, pz = x[v * 3 + 2] - 0.5;
        x[v * 3] = 0.5 + std::cos(0.3) * px - std::sin(0.3) * pz;
        x[v * 3 + 2] = 0.5 + std::sin(0.3) * px + std::cos(0.3) * pz;
    }
    (void)nv;
    x = jiggle(x, 5e-5, 11);
    const ContactSet& set = sim.contact()->contacts(x);
    int kinds[4] = { 0, 0, 0, 0 };
    for (const Contact& c : set)
        ++kinds[int(c.kind)];
    EXPECT_GT(kinds[int(ContactKind::VERTEX_FACE)], 0);
    EXPECT_GT(kinds[int(ContactKind::EDGE_EDGE)], 0);
    EXPECT_GT(kinds[int(ContactKind::VERTEX_PLANE)], 0);
    const Check c = fd_check(sim, x);
    EXPECT_GT(c.gradient_norm, 0);
    EXPECT_LT(c.gradient_error, 1e-5);
    EXPECT_LT(c.hessian_error, 1e-5);
}
