// Periodic scenes ("periodic" in a scene file; forward/periodic/periodic_cell.hpp): a cell
// compressed by a prescribed macro gradient against the same block held by rollers (Dirichlet
// conditions: an independent path through the solver), free lateral components against the
// material's uniaxial closed form, every integrator, the trajectory's macro datasets, and errors
// naming the field.

#include "forward/common/error.hpp"
#include "forward/io/trajectory_reader.hpp"
#include "forward/io/trajectory_writer.hpp"
#include "tests/forward/test_utils.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <string>

using namespace diffipc;
using json = nlohmann::json;

namespace {

const json NONE = nullptr;

/// G with G_xx = xx and the other entries `rest` (0 or null: free lateral diagonal).
json gradient(int dim, const json& xx, const json& lateral)
{
    json G = json::array();
    for (int i = 0; i < dim; ++i) {
        json row = json::array();
        for (int j = 0; j < dim; ++j)
            row.push_back(i == 0 && j == 0 ? xx : i == j ? lateral : json(0));
        G.push_back(row);
    }
    return G;
}

/// A block [0, 1] x [0, 0.8] (x [0, 1]; 5 cells along x) of `model`, a periodic cell with macro gradient G, over
/// `steps` steps.
json periodic_block(int dim, const json& G, int steps, const std::string& model = "neo_hookean",
    const std::string& integrator = "static")
{
    json s = dim == 2 ? test::box_scene(2, { 1, 0.8 }, { 5, 4 }, model, 1e5, 0.3, 1000)
                      : test::box_scene(3, { 1, 0.8, 1 }, { 5, 2, 2 }, model, 1e5, 0.3, 1000);
    s["periodic"] = { { "gradient", G } };
    s["time"] = { { "integrator", integrator }, { "dt", 1.0 / steps }, { "steps", steps } };
    s["solver"] = { { "residual_tolerance", 1e-10 } };
    return s;
}

std::string message(const json& s)
{
    try {
        test::make_scene(s);
    } catch (const InputError& e) {
        return e.what();
    }
    return "no error";
}

} // namespace

TEST(PeriodicScene, PrescribedCompressionMatchesTheBlockBetweenRollers)
{
    // G_xx = -0.3 t, every other component 0: the cell is compressed along x and held laterally.
    // The same block with u_x prescribed on its x faces and u_y (u_z) = 0 on the others is
    // homogeneous too: the same states, found without the periodic code.
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE(dim);
        const json s = periodic_block(dim, gradient(dim, "-0.3*t", 0), 3);
        Simulator cell(test::make_scene(s));
        const Trajectory& tr = cell.run();
        ASSERT_EQ(tr.final_status, StepStatus::CONVERGED) << tr.failure_message;

        json r = s;
        r.erase("periodic");
        const std::vector<double> extent = { 1.0, 0.8, 1.0 };
        json dir = json::array();
        for (int axis = 0; axis < dim; ++axis)
            for (int side = 0; side < 2; ++side) {
                std::vector<double> lo(size_t(dim), -1), hi(size_t(dim), 2);
                lo[size_t(axis)] = side * extent[size_t(axis)] - 1e-6;
                hi[size_t(axis)] = side * extent[size_t(axis)] + 1e-6;
                json c = json::array();
                for (int a = 0; a < dim; ++a)
                    c.push_back(a != axis ? NONE : axis == 0 && side == 1 ? json("-0.3*t") : json(0));
                dir.push_back({ { "body", 0 }, { "region", test::region(lo, hi) }, { "displacement", c } });
            }
        r["dirichlet"] = dir;
        Simulator rollers(test::make_scene(r));
        const Trajectory& ref = rollers.run();
        ASSERT_EQ(ref.final_status, StepStatus::CONVERGED) << ref.failure_message;
        for (int k = 1; k <= 3; ++k) {
            SCOPED_TRACE(k);
            EXPECT_LE((tr.step(k).positions - ref.step(k).positions).lpNorm<Eigen::Infinity>(), 1e-9);
            EXPECT_NEAR(tr.step(k).macro_gradient[0], -0.1 * k, 1e-15);
        }
    }
}

TEST(PeriodicScene, FreeLateralComponentsGiveTheUniaxialContraction)
{
    // Linear elasticity, 1% compression along x, the lateral diagonal components free (null in
    // "gradient"): plane strain contracts by lambda / (lambda + 2 mu) of the strain, 3D by nu;
    // the free components of the average stress vanish and the loaded one is E' eps.
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE(dim);
        Simulator cell(test::make_scene(periodic_block(dim, gradient(dim, "-0.01*t", NONE), 1, "linear")));
        const Trajectory& tr = cell.run();
        ASSERT_EQ(tr.final_status, StepStatus::CONVERGED) << tr.failure_message;
        const double E = 1e5, nu = 0.3, l = E * nu / ((1 + nu) * (1 - 2 * nu)), m = E / (2 * (1 + nu));
        const double ratio = dim == 2 ? l / (l + 2 * m) : nu;
        const double modulus = dim == 2 ? 4 * m * (l + m) / (l + 2 * m) : E;
        const VectorXd& G = tr.step(1).macro_gradient;
        const VectorXd& P = tr.step(1).macro_stress;
        for (int i = 1; i < dim; ++i) {
            EXPECT_NEAR(G[i * dim + i], 0.01 * ratio, 1e-12);
            EXPECT_LE(std::abs(P[i * dim + i]), 1e-9 * modulus);
        }
        EXPECT_NEAR(P[0], -0.01 * modulus, 1e-9 * modulus);
    }
}

TEST(PeriodicScene, EveryIntegratorRunsAndHitsThePrescribedGradient)
{
    for (const char* integrator : { "static", "implicit_euler", "bdf2", "newmark" }) {
        SCOPED_TRACE(integrator);
        json s = periodic_block(2, gradient(2, "-0.2*t", NONE), 4, "neo_hookean", integrator);
        s["time"]["dt"] = 0.01;
        Simulator cell(test::make_scene(s));
        const Trajectory& tr = cell.run();
        ASSERT_EQ(tr.final_status, StepStatus::CONVERGED) << tr.failure_message;
        for (int k = 1; k <= 4; ++k) {
            EXPECT_NEAR(tr.step(k).macro_gradient[0], -0.002 * k, 1e-15);
            EXPECT_LE(tr.step(k).residual, 1e-10);
        }
    }
}

TEST(PeriodicScene, MacroDatasetsAreWrittenAndReadBack)
{
    Simulator cell(test::make_scene(periodic_block(2, gradient(2, "-0.3*t", NONE), 2)));
    const Trajectory& tr = cell.run();
    ASSERT_EQ(tr.final_status, StepStatus::CONVERGED) << tr.failure_message;
    const std::string path = testing::TempDir() + "periodic_macro.h5";
    write_hdf5(path, cell.mesh(), tr, false);
    const StoredTrajectory stored = read_trajectory(path);
    ASSERT_EQ(stored.trajectory.committed(), 2);
    for (int k = 1; k <= 2; ++k) {
        EXPECT_EQ(stored.trajectory.step(k).macro_gradient, tr.step(k).macro_gradient);
        EXPECT_EQ(stored.trajectory.step(k).macro_stress, tr.step(k).macro_stress);
    }
    std::remove(path.c_str());
}

TEST(PeriodicScene, BadInputIsAnErrorNamingTheField)
{
    const json good = periodic_block(2, gradient(2, "-0.3*t", NONE), 2);
    EXPECT_EQ(message(good), "no error");
    // Every key is optional: an empty "periodic" holds the cell at its size (G = 0).
    json empty = good;
    empty["periodic"] = json::object();
    EXPECT_EQ(message(empty), "no error");
    json only_free = good;
    only_free["periodic"] = { { "free", { "yy" } } };
    EXPECT_EQ(message(only_free), "no error");
    // A mesh that is not periodic: the block turned by 10 degrees.
    json turned = good;
    turned["bodies"][0]["rotation"] = { 10 };
    EXPECT_NE(message(turned).find("bodies[0].mesh: the mesh is not periodic along x: vertex"), std::string::npos)
        << message(turned);
    // A box that does not fit the mesh.
    json box = good;
    box["periodic"]["box"] = { { "min", { 0, 0 } }, { "max", { 2, 0.8 } } };
    EXPECT_EQ(message(box).find("periodic.box: along the periodic axis x the box spans [0, 2] m"), 0u) << message(box);
    // A component both prescribed and free, a free rotation, a free component along a
    // non-periodic axis, unknown axes and components.
    json both = good;
    both["periodic"]["free"] = { "xx" };
    EXPECT_EQ(message(both), "periodic.free[0]: G_xx is both prescribed (periodic.gradient[0][0]) and free");
    json rotation = good;
    rotation["periodic"]["gradient"] = { { "-0.3*t", nullptr }, { nullptr, 0 } };
    EXPECT_NE(message(rotation).find("periodic.gradient: G_xy and G_yx are both free"), std::string::npos)
        << message(rotation);
    json axis = good;
    axis["periodic"]["axes"] = { "x" };
    EXPECT_NE(message(axis).find("G_yy multiplies the non-periodic axis y"), std::string::npos) << message(axis);
    json bad_axis = good;
    bad_axis["periodic"]["axes"] = { "w" };
    EXPECT_EQ(message(bad_axis).find("periodic.axes[0]: expected one of xy"), 0u) << message(bad_axis);
    json bad_name = good;
    bad_name["periodic"]["gradient"] = gradient(2, "-0.3*t", 0);
    bad_name["periodic"]["free"] = { "yq" };
    EXPECT_EQ(message(bad_name).find("periodic.free[0]: expected a component"), 0u) << message(bad_name);
    // Contact and friction across the boundary are built; not supported: Dirichlet conditions.
    json contact = good;
    contact["contact"] = { { "dhat", 1e-3 } };
    contact["friction"] = { { "coefficient", 0.2 } };
    EXPECT_EQ(message(contact), "no error");
    json dirichlet = good;
    dirichlet["dirichlet"]
        = { { { "body", 0 }, { "region", test::region({ -1, -1 }, { 0.01, 2 }) }, { "displacement", { 0, 0 } } } };
    EXPECT_NE(message(dirichlet).find("periodic: Dirichlet conditions"), std::string::npos) << message(dirichlet);
}

namespace {

/// The cell-average stress of a two-layer linear laminate (E_a for x < 0.4, E_b beyond, layers
/// normal to x) under the prescribed gradient G (every component prescribed), one static step.
VectorXd laminate_stress(int dim, double E_a, double E_b, double nu, const json& G, double shift = 0)
{
    json s = periodic_block(dim, G, 1, "linear");
    if (shift != 0)
        s["bodies"][0]["translation"] = dim == 2 ? json { shift, -2 * shift } : json { shift, -2 * shift, 3 * shift };
    Simulator sim(test::make_scene(s));
    const Mesh& m = sim.mesh();
    VectorXd E(m.num_elements()), Nu = VectorXd::Constant(m.num_elements(), nu);
    for (Index e = 0; e < m.num_elements(); ++e) {
        double cx = 0;
        for (int a = 0; a <= dim; ++a)
            cx += m.rest_positions(m.elements(e, a), 0) / (dim + 1);
        E[e] = cx - shift < 0.4 ? E_a : E_b;
    }
    sim.set_element_materials(E, Nu);
    const Trajectory& tr = sim.run();
    EXPECT_EQ(tr.final_status, StepStatus::CONVERGED) << tr.failure_message;
    return tr.step(1).macro_stress;
}

} // namespace

TEST(PeriodicScene, LaminatesGiveTheVoigtAndReussBoundsWhereTheyAreExact)
{
    // Layers normal to x, volume fractions 0.4 and 0.6, linear elasticity. A strain normal to the
    // layers (G = diag(eps, 0 ...)): the normal stress is continuous, so the P-wave moduli
    // M = lambda + 2 mu combine harmonically (Reuss). A strain along the layers with nu = 0: each
    // layer strains alike, so the moduli combine arithmetically (Voigt).
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE(dim);
        const double Ea = 1e5, Eb = 7e5, eps = 1e-3, fa = 0.4, fb = 0.6;
        json normal = gradient(dim, eps, 0);
        {
            const double nu = 0.3;
            const auto M = [&](double E) { return E * (1 - nu) / ((1 + nu) * (1 - 2 * nu)); };
            const double reuss = 1 / (fa / M(Ea) + fb / M(Eb));
            const VectorXd P = laminate_stress(dim, Ea, Eb, nu, normal);
            EXPECT_NEAR(P[0], reuss * eps, 1e-9 * reuss * eps);
            // The same cell shifted in space: the same average stress.
            const VectorXd shifted = laminate_stress(dim, Ea, Eb, nu, normal, 0.37);
            EXPECT_LE((shifted - P).lpNorm<Eigen::Infinity>(), 1e-9 * reuss * eps);
        }
        {
            json along = gradient(dim, 0, 0);
            along[1][1] = eps;
            const double voigt = fa * Ea + fb * Eb; // nu = 0: M = E
            const VectorXd P = laminate_stress(dim, Ea, Eb, 0.0, along);
            EXPECT_NEAR(P[dim + 1], voigt * eps, 1e-9 * voigt * eps);
        }
    }
}
