// Finite-difference checks of the assembled barrier potential (value ->
// gradient -> true Hessian) at states with active contacts of every kind:
// 2D vertex-edge and vertex-plane, 3D vertex-face, edge-edge (mollified) and
// vertex-plane.

#include "../potential_fd.hpp"
#include "contact_scenes.hpp"

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
    Simulator sim(test::make_scene(test::rings_on_plane({ { "dhat", 1e-3 }, { "kappa", 1.0 } })));
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
    Simulator sim(test::make_scene(test::boxes_on_plane({ { "dhat", 1e-3 }, { "kappa", 1.0 } })));
    VectorXd x = test::turn_upper_box(sim, 0.3);
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
