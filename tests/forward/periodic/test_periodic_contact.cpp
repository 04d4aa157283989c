// Contact across a periodic cell's boundary (forward/periodic/contact_images.hpp): each pair of
// the infinite tiling counted once (the cell against a cell of two periods and a differently cut
// cell of the same tiling), the barrier's and the friction's derivatives through the image map
// against finite differences (friction counted once too), a compression whose posts touch across the boundary kept
// intersection-free on the tiled copies by the independent intersection test (and crossing without contact), the same
// stress curve for any cut of the periodic medium, and the homogenized stress with the barrier's
// part against the derivative of the relaxed energy.

#include "forward/contact/friction/friction_potential.hpp"
#include "forward/contact/intersection.hpp"
#include "forward/periodic/tiling.hpp"
#include "tests/forward/periodic/post_cell.hpp"
#include "tests/forward/potential_fd.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

using namespace diffipc;
using json = nlohmann::json;

namespace {

std::string mesh_path(int dim, const std::string& name)
{
    return "/tmp/diffipc_post_cell_" + std::to_string(dim) + "d_" + name + "_" + std::to_string(::getpid()) + ".msh";
}

std::unique_ptr<Simulator> post_simulator(
    int dim, const std::string& name, double strain, int steps, const json& kappa, int repeats = 1, double shift = 0)
{
    const std::string path = mesh_path(dim, name);
    const json s = test::post_cell_scene(dim, path, strain, steps, kappa, repeats, shift);
    auto sim = std::make_unique<Simulator>(test::make_scene(s));
    std::remove(path.c_str());
    return sim;
}

/// A deformation of the tiling: phi(Y) = Y + G Y + w(Y), w periodic and smooth but for the up
/// post, lifted by 0.093 so that its top comes within about 0.005 m of the next cell's down post
/// (dhat is 0.01); G_yy = -0.02. At the cell's vertex X: phi(X + shift e_y).
VectorXd near_contact_positions(const Mesh& mesh, double shift)
{
    const int d = mesh.dim;
    VectorXd x(mesh.num_dofs());
    for (Index v = 0; v < mesh.num_vertices(); ++v) {
        VectorXd Y = mesh.rest_positions.row(v).transpose();
        Y[1] += shift;
        const double yp = Y[1] - std::floor(Y[1]);
        VectorXd p = Y;
        p[1] += -0.02 * Y[1];
        p[0] += 0.01 * std::sin(2 * M_PI * yp) + 0.003 * std::cos(2 * M_PI * Y[0]);
        p[1] += 0.001 * std::cos(2 * M_PI * (2 * Y[0] - yp));
        if (d == 3) { // no two surface edges exactly parallel
            p[2] += 0.004 * std::sin(2 * M_PI * (Y[0] + 2 * yp)) + 0.002 * std::cos(2 * M_PI * Y[2] / 0.2);
            p[0] += 0.002 * std::sin(2 * M_PI * (Y[2] / 0.2 + yp));
            p[1] += 0.001 * std::sin(2 * M_PI * (Y[2] / 0.2 + 3 * Y[0]));
        }
        if (Y[0] > 0.38 && Y[0] < 0.62 && yp >= 0.75 - 1e-9 && yp <= 0.95 + 1e-9) // the sheared up post
            p[1] += 0.093;
        x.segment(v * d, d) = p;
    }
    return x;
}

CollisionMesh tiled_surface(const Mesh& m) { return build_collision_mesh(m, { 1 }, { 0 }); }

/// A potential's gradient and Hessian at x against central differences (four random directions,
/// h = 1e-7 m; the near-contact pairs are 0.005 m apart).
void expect_derivatives_match(const Potential& P, const Mesh& mesh, const VectorXd& x)
{
    const test::PotentialFD e = test::potential_fd(P, mesh, mesh.dim, x, 1e-7, 0, false);
    EXPECT_GT(e.gradient_norm, 0);
    EXPECT_LE(e.gradient, 1e-6);
    EXPECT_LE(e.hessian, 1e-6);
}

/// The independent check of a state: the 3 x 3 (x 3) tiling of the deformed cell has no crossing
/// surfaces and no inverted element.
void expect_tiling_valid(const Simulator& sim, const VectorXd& x, const VectorXd& G, const std::string& what)
{
    const PeriodicSpec& p = sim.scene().periodic;
    const Tiling t = tile_cell(sim.mesh(), p.box, p.pairing, x, G, 1);
    EXPECT_EQ(find_intersection(tiled_surface(t.mesh), t.positions, true), "") << what;
    EXPECT_EQ(count_inverted_elements(t.mesh, t.positions), 0) << what;
}

} // namespace

TEST(PeriodicContact, EachPairOfTheTilingIsCountedOnce)
{
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE("dim " + std::to_string(dim));
        const auto cell = post_simulator(dim, "cell", -0.2, 1, 1.0);
        const auto twice = post_simulator(dim, "twice", -0.2, 1, 1.0, 2);
        const auto cut = post_simulator(dim, "cut", -0.2, 1, 1.0, 1, 0.5);
        const VectorXd x = near_contact_positions(cell->mesh(), 0);
        const VectorXd x2 = near_contact_positions(twice->mesh(), 0);
        const VectorXd xc = near_contact_positions(cut->mesh(), 0.5);
        const ContactPotential& B = *cell->contact();
        const double b = B.barrier_value(x);
        ASSERT_GT(b, 0) << "the posts are not within dhat across the boundary";
        // In the cell the touching posts meet across y = 1 only: the pairs involve images.
        const Index nv = cell->mesh().num_vertices();
        for (const Contact& c : B.contacts(x)) {
            bool image = false;
            for (int k = 0; k < c.num_vertices(); ++k)
                image = image || c.vertices[size_t(k)] >= nv;
            EXPECT_TRUE(image) << "a contact within the cell";
        }
        // Two periods: one gap inside, one across the boundary; the other cut: the gap inside.
        EXPECT_NEAR(twice->contact()->barrier_value(x2), 2 * b, 1e-10 * b);
        EXPECT_NEAR(cut->contact()->barrier_value(xc), b, 1e-10 * b);
        EXPECT_EQ(twice->contact()->contacts(x2).size(), 2 * B.contacts(x).size());
        EXPECT_EQ(cut->contact()->contacts(xc).size(), B.contacts(x).size());
        EXPECT_NEAR(B.min_distance(x, 0.05), cut->contact()->min_distance(xc, 0.05), 1e-12);
        EXPECT_NEAR(B.min_distance(x, 0.05), 0.005, 2e-3);
    }
}

TEST(PeriodicContact, BarrierDerivativesThroughTheImagesMatchFiniteDifferences)
{
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE("dim " + std::to_string(dim));
        const auto sim = post_simulator(dim, "fd", -0.2, 1, 1.0);
        expect_derivatives_match(*sim->contact(), sim->mesh(), near_contact_positions(sim->mesh(), 0));
    }
}

TEST(PeriodicContact, FrictionThroughTheImagesCountsEachPairOnceAndMatchesFiniteDifferences)
{
    // Friction lagged at the near-contact state (posts 0.005 m apart across the boundary), the
    // step started from a state slid by a periodic field: its value in the cell against a cell of
    // two periods, and its gradient and Hessian through the image map against central differences.
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE("dim " + std::to_string(dim));
        const auto cell = post_simulator(dim, "friction", -0.2, 1, 1.0);
        const auto twice = post_simulator(dim, "friction_twice", -0.2, 1, 1.0, 2);
        const auto friction_of = [&](const Simulator& sim, const VectorXd& x, const VectorXd& start) {
            const ContactPotential& B = *sim.contact();
            const std::vector<int>& groups = B.collision_mesh().vertex_group;
            auto D = std::make_unique<FrictionPotential>(dim, std::vector<double> { 0.3 }, sim.mesh().vertex_body, 0.1);
            D->set_images(B.images(), Eigen::Map<const VectorXi>(groups.data(), Index(groups.size())));
            D->lag(B, x);
            D->set_step(start, 1.0);
            return D;
        };
        // The step's start: each vertex back by a smooth periodic slide (0.002 m at most).
        const auto slid = [&](const Mesh& mesh, const VectorXd& x) {
            VectorXd start = x;
            for (Index v = 0; v < mesh.num_vertices(); ++v) {
                const double X = mesh.rest_positions(v, 0), Y = mesh.rest_positions(v, 1);
                start[v * dim] -= 0.002 * std::sin(2 * M_PI * Y);
                start[v * dim + dim - 1] -= 0.001 * std::cos(2 * M_PI * (X + Y));
            }
            return start;
        };
        const VectorXd x = near_contact_positions(cell->mesh(), 0), x2 = near_contact_positions(twice->mesh(), 0);
        const auto D = friction_of(*cell, x, slid(cell->mesh(), x));
        const auto D2 = friction_of(*twice, x2, slid(twice->mesh(), x2));
        ASSERT_GT(D->lagged().size(), 0u);
        const double value = D->value(x);
        ASSERT_GT(value, 0);
        EXPECT_NEAR(D2->value(x2), 2 * value, 1e-10 * value);
        EXPECT_EQ(D2->lagged().size(), 2 * D->lagged().size());

        expect_derivatives_match(*D, cell->mesh(), x);
    }
}

TEST(PeriodicContact, PostsTouchingAcrossTheBoundaryStayIntersectionFreeOnTheTiling)
{
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE("dim " + std::to_string(dim));
        // The gap closes at G_yy = -0.1; beyond -0.18 the cell buckles (without contact too).
        const int steps = dim == 2 ? 8 : 4;
        const auto sim = post_simulator(dim, "run", -0.16, steps, nullptr);
        const Trajectory& tr = sim->run();
        ASSERT_EQ(tr.committed(), steps) << to_string(sim->last_attempt().status);
        for (int k = 1; k <= steps; ++k)
            expect_tiling_valid(*sim, tr.step(k).positions, tr.step(k).macro_gradient, "step " + std::to_string(k));
        const StepRecord& last = tr.step(steps);
        EXPECT_GT(last.active_contacts, 0);
        EXPECT_GT(last.min_distance, 0);
        EXPECT_LT(last.min_distance, 0.01);
        // The free lateral component carries no stress; the posts push back along y.
        EXPECT_LT(last.macro_stress[dim + 1], 0);
        EXPECT_LE(std::abs(last.macro_stress[0]), 1e-6 * std::abs(last.macro_stress[dim + 1]));

        // Without contact the same compression drives the posts through each other: the check
        // above finds it.
        const std::string path = mesh_path(dim, "free");
        json s = test::post_cell_scene(dim, path, -0.16, steps, nullptr);
        s.erase("contact");
        Simulator free(test::make_scene(s));
        std::remove(path.c_str());
        const Trajectory& ft = free.run();
        ASSERT_EQ(ft.committed(), steps) << to_string(free.last_attempt().status);
        const PeriodicSpec& p = free.scene().periodic;
        const Tiling t
            = tile_cell(free.mesh(), p.box, p.pairing, ft.step(steps).positions, ft.step(steps).macro_gradient, 1);
        EXPECT_NE(find_intersection(tiled_surface(t.mesh), t.positions, true), "");
    }
}

TEST(PeriodicContact, TheStressCurveDoesNotDependOnWhereTheCellIsCut)
{
    // The same periodic medium cut at y = 0, 0.25 and 0.5 (the grid and the pattern shifted
    // together, so that the three meshes are one tiling's): the pinned class, the origin of G,
    // the pairing and the images differ, and at 0.5 the posts meet inside the cell instead of
    // across its boundary. The homogenized stress of every step is the same.
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE("dim " + std::to_string(dim));
        const int steps = dim == 2 ? 8 : 4;
        std::vector<MatrixXd> curves;
        for (double shift : { 0.0, 0.25, 0.5 }) {
            const auto sim = post_simulator(dim, "cut", -0.16, steps, 1e4, 1, shift);
            const Trajectory& tr = sim->run();
            ASSERT_EQ(tr.committed(), steps) << to_string(sim->last_attempt().status);
            EXPECT_GT(tr.step(steps).active_contacts, 0);
            MatrixXd curve(steps, dim * dim);
            for (int k = 1; k <= steps; ++k)
                curve.row(k - 1) = tr.step(k).macro_stress.transpose();
            curves.push_back(curve);
        }
        const double scale = curves[0].cwiseAbs().maxCoeff();
        for (size_t c = 1; c < curves.size(); ++c)
            EXPECT_LE((curves[c] - curves[0]).cwiseAbs().maxCoeff(), 1e-7 * scale) << "cut " << c;
    }
}

TEST(PeriodicContact, HomogenizedStressIsTheDerivativeOfTheRelaxedEnergy)
{
    // W(g) = min over the fluctuation and the free components of Psi + kappa B at G_yy = g: dW/dg
    // = |Y| P_yy (envelope theorem), the barrier's virial across the boundary included.
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE("dim " + std::to_string(dim));
        const double g = -0.14, dg = 1e-3;
        const int steps = 7;
        double W[2];
        for (int side = 0; side < 2; ++side) {
            const auto sim = post_simulator(dim, "w", g + (side ? dg : -dg), steps, 1e4);
            ASSERT_EQ(sim->run().committed(), steps) << to_string(sim->last_attempt().status);
            W[side] = sim->problem().energy(sim->positions());
        }
        const auto sim = post_simulator(dim, "mid", g, steps, 1e4);
        ASSERT_EQ(sim->run().committed(), steps) << to_string(sim->last_attempt().status);
        const VectorXd stress = sim->macro_stress(sim->positions());
        const VectorXd elastic = sim->periodic()->average_stress(sim->elastic(), sim->positions());
        const double volume = sim->periodic()->volume();
        ASSERT_GT(sim->trajectory().step(steps).active_contacts, 0);
        // The barrier's virial (its forces times their rest lever, the gap) is a part of the stress
        // ten times the tolerance below: without it the identity would fail.
        const double tolerance = 1e-3 * std::abs(stress[dim + 1]);
        EXPECT_GT(std::abs(stress[dim + 1] - elastic[dim + 1]), 10 * tolerance);
        EXPECT_NEAR((W[1] - W[0]) / (2 * dg) / volume, stress[dim + 1], tolerance);
    }
}
