// A cell family's design variables (shape_opt/microstructure/cell_family.hpp): the variables the
// symmetry leaves, a design that keeps the symmetry and the periodic connections (checked on the
// solid's level set and the moved nodes, not through the family's orbits), bounds that name the
// variable, and the family files' errors.

#include "shape_opt/microstructure/cell_family.hpp"

#include "forward/common/error.hpp"
#include "forward/scene/json_field.hpp"

#include <gtest/gtest.h>

#include <random>

using namespace diffipc;

namespace {

const std::string kTopologies = std::string(DIFFIPC_SOURCE_DIR) + "/shape_opt/microstructure/topologies/";

VectorXd random_design(const CellFamily& f, unsigned seed)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    VectorXd p(f.size());
    for (Index v = 0; v < f.size(); ++v)
        p[v] = f.lower()[v] + u(rng) * (f.upper()[v] - f.lower()[v]);
    return p;
}

std::string error_field(const std::function<void()>& f)
{
    try {
        f();
    } catch (const InputError& e) {
        return e.field();
    }
    return "(no error)";
}

} // namespace

TEST(CellFamily, TheReentrantCellsVariablesAreTheOnesItsMirrorsLeave)
{
    const CellFamily f = read_cell_family(kTopologies + "reentrant.json");
    // Nodes 0-3 (x = +-1, y = +-0.6) move together along y; nodes 4, 5 (0, -+0.3) along y; nodes
    // 6, 7 (0, -+1) are fixed by both the mirror x -> -x and the sides. Three edge orbits.
    const std::vector<std::string> expected { "node[0].y", "node[4].y", "thickness[0]", "thickness[2]", "thickness[6]",
        "blend", "width" };
    EXPECT_EQ(f.names(), expected);
    EXPECT_EQ(f.width_index(), 6);
    EXPECT_TRUE((f.initial().array() >= f.lower().array()).all() && (f.initial().array() <= f.upper().array()).all());
}

TEST(CellFamily, DesignsKeepTheSymmetryAndThePeriodicConnections)
{
    for (const char* name : { "square_grid", "diamond", "diamond_stop", "reentrant", "curved_beam" }) {
        SCOPED_TRACE(name);
        const CellFamily f = read_cell_family(kTopologies + name + ".json");
        const WireGraph& g = f.graph();
        for (unsigned seed = 1; seed <= 5; ++seed) {
            // At the smallest blend the 3 x 3 window of images (cell_sdf.hpp) leaves out terms
            // below exp(-1.7 / k) ~ 1e-74 of the sum: mirror images agree to round-off.
            VectorXd p = random_design(f, seed);
            p[f.width_index() - 1] = f.lower()[f.width_index() - 1];
            ASSERT_EQ(f.names()[size_t(f.width_index() - 1)], "blend");
            const CellParameters c = f.cell_parameters(p);
            const MatrixXd moved = g.nodes + c.offsets;
            // Nodes stay in the cell, nodes on a side stay on it.
            EXPECT_LE(moved.cwiseAbs().maxCoeff(), 1 + 1e-12);
            for (Index i = 0; i < g.nodes.rows(); ++i)
                for (int a = 0; a < 2; ++a)
                    if (std::abs(g.nodes(i, a)) == 1)
                        EXPECT_EQ(moved(i, a), g.nodes(i, a));
            // The solid keeps the symmetry: phi at mirrored points.
            const CellSDF phi(g, c);
            std::mt19937 rng(seed);
            std::uniform_real_distribution<double> u(-1, 1);
            for (int k = 0; k < 50; ++k) {
                const Eigen::Vector2d y(u(rng), u(rng));
                const CellSymmetry s = f.symmetry();
                if (s == CellSymmetry::REFLECTION_X || s == CellSymmetry::REFLECTION_XY)
                    EXPECT_NEAR(phi.value(Eigen::Vector2d(-y.x(), y.y())), phi.value(y), 1e-12);
                if (s == CellSymmetry::REFLECTION_Y || s == CellSymmetry::REFLECTION_XY)
                    EXPECT_NEAR(phi.value(Eigen::Vector2d(y.x(), -y.y())), phi.value(y), 1e-12);
            }
        }
    }
}

TEST(CellFamily, TheMapIsLinearWithItsJacobian)
{
    const CellFamily f = read_cell_family(kTopologies + "curved_beam.json");
    const VectorXd p = random_design(f, 7);
    const VectorXd c = f.cell_parameters(p).flatten();
    EXPECT_LT((f.jacobian() * p - c).norm(), 1e-14);
    EXPECT_TRUE(f.jacobian().col(f.width_index()).isZero());
}

TEST(CellFamily, ADesignBeyondItsBoundsNamesTheVariable)
{
    const CellFamily f = read_cell_family(kTopologies + "reentrant.json");
    VectorXd p = f.upper();
    EXPECT_NO_THROW(f.cell_parameters(p));
    EXPECT_NO_THROW(f.cell_parameters(f.lower()));
    p[1] += 1e-6;
    EXPECT_EQ(error_field([&] { f.cell_parameters(p); }), "design.node[4].y");
    p = f.lower();
    p[f.width_index()] *= 0.99;
    EXPECT_EQ(error_field([&] { f.check(p, "x"); }), "x.width");
    p = f.initial();
    p[3] = std::nan("");
    EXPECT_EQ(error_field([&] { f.check(p, "x"); }), "x.thickness[2]");
    EXPECT_EQ(error_field([&] { f.check(VectorXd::Zero(3), "x"); }), "x");
}

TEST(CellFamily, AGraphWithoutTheSymmetryOrBadRangesIsAnInputError)
{
    const WireGraph g = parse_wire_graph("v -1 0\nv 0.3 0\nv 1 0\nl 1 2 3\n", "lopsided.obj");
    CellFamily::Settings s;
    EXPECT_NO_THROW(CellFamily(g, s, "f"));
    s.symmetry = CellSymmetry::REFLECTION_X;
    EXPECT_EQ(error_field([&] { CellFamily(g, s, "f"); }), "f.symmetry");
    s.symmetry = CellSymmetry::NONE;
    s.thickness = { 0.1, 0.2, 0.3 };
    EXPECT_EQ(error_field([&] { CellFamily(g, s, "f"); }), "f.thickness.initial");
    s.thickness = { 0.1, 0.0, 0.3 };
    EXPECT_EQ(error_field([&] { CellFamily(g, s, "f"); }), "f.thickness.bounds");

    const nlohmann::json bad_symmetry = { { "graph", kTopologies + "diamond.obj" }, { "symmetry", "rotation" } };
    EXPECT_EQ(error_field([&] { parse_cell_family(JsonField(bad_symmetry, "family"), ""); }), "family.symmetry");
    const nlohmann::json bad_key = { { "graph", kTopologies + "diamond.obj" }, { "thicknes", 1 } };
    EXPECT_NE(error_field([&] { parse_cell_family(JsonField(bad_key, "family"), ""); }), "(no error)");
    EXPECT_EQ(error_field([] { read_cell_family("/nonexistent/family.json"); }), "/nonexistent/family.json");
}
