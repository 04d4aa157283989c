// The solid of a microstructure cell (shape_opt/microstructure/cell_sdf.hpp): periodic with the
// cell, the distance to a lone thick edge where the others are far, the smooth union below the
// plain one by at most k log(#terms), and its gradients in x and in every parameter against
// central differences.

#include "shape_opt/microstructure/cell_sdf.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace diffipc;

namespace {

/// A re-entrant-like graph with nodes off the axes, some edges across the cell's faces.
WireGraph test_graph()
{
    return parse_wire_graph("v -1 -0.2\nv -0.3 0.1\nv 0.4 -0.35\nv 1 -0.2\nv 0.1 0.9\nv 0.1 -1\n"
                            "l 1 2 3 4\nl 2 5\nl 3 6\n",
        "test.obj");
}

CellParameters test_parameters(const WireGraph& g)
{
    CellParameters p;
    p.offsets = MatrixXd::Zero(g.nodes.rows(), 2);
    p.offsets(1, 0) = 0.05;
    p.offsets(2, 1) = -0.04;
    p.thickness = VectorXd::LinSpaced(g.edges.rows(), 0.12, 0.2);
    p.blend = 0.04;
    return p;
}

} // namespace

TEST(CellSDF, IsPeriodicWithTheCell)
{
    const WireGraph g = test_graph();
    const CellSDF phi(g, test_parameters(g));
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int i = 0; i < 20; ++i) {
        const Eigen::Vector2d x(u(rng), u(rng));
        EXPECT_NEAR(phi.value(x + Eigen::Vector2d(2, 0)), phi.value(x), 1e-12);
        EXPECT_NEAR(phi.value(x + Eigen::Vector2d(0, -2)), phi.value(x), 1e-12);
    }
}

TEST(CellSDF, ALoneEdgeGivesItsDistanceAndTheUnionLiesBelowTheMinimum)
{
    // One short edge in the middle of the cell, thickness 0.1: far from its images, phi is its
    // distance less 0.05 up to the blend's k log(1 + small).
    const WireGraph g = parse_wire_graph("v -0.2 0\nv 0.2 0\nl 1 2\n", "one.obj");
    CellParameters p;
    p.offsets = MatrixXd::Zero(2, 2);
    p.thickness = VectorXd::Constant(1, 0.1);
    p.blend = 0.01;
    const CellSDF phi(g, p);
    EXPECT_NEAR(phi.value(Eigen::Vector2d(0, 0.3)), 0.3 - 0.05, 1e-12);
    EXPECT_NEAR(phi.value(Eigen::Vector2d(0.5, 0)), 0.3 - 0.05, 1e-12);
    EXPECT_NEAR(phi.value(Eigen::Vector2d(0, 0)), -0.05, 1e-12);
    // Two edges' union: at most k log(#terms) below the smaller distance, and never above it.
    const WireGraph g2 = test_graph();
    const CellSDF phi2(g2, test_parameters(g2));
    const double k = phi2.parameters().blend, bound = k * std::log(9.0 * double(g2.edges.rows()));
    for (double y : { -0.8, -0.3, 0.0, 0.45 }) {
        const Eigen::Vector2d x(0.2, y);
        CellParameters hard = phi2.parameters();
        hard.blend = 1e-6;
        const double plain = CellSDF(g2, hard).value(x);
        EXPECT_LE(phi2.value(x), plain + 1e-5);
        EXPECT_GE(phi2.value(x), plain - bound);
    }
}

TEST(CellSDF, GradientsInPositionAndEveryParameterMatchCentralDifferences)
{
    const WireGraph g = test_graph();
    const CellParameters p0 = test_parameters(g);
    const VectorXd flat = p0.flatten();
    const Index n = g.nodes.rows(), m = g.edges.rows();
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-1, 1);
    const double h = 1e-6;
    int checked = 0;
    for (int i = 0; i < 40; ++i) {
        const Eigen::Vector2d x(u(rng), u(rng));
        const CellSDF phi(g, p0);
        const Eigen::Vector2d gx = phi.gradient(x);
        for (int a = 0; a < 2; ++a) {
            const Eigen::Vector2d e = Eigen::Vector2d::Unit(a) * h;
            const double fd = (phi.value(x + e) - phi.value(x - e)) / (2 * h);
            EXPECT_NEAR(fd, gx[a], 1e-7) << "x (" << x.transpose() << ") axis " << a;
        }
        const VectorXd gp = phi.parameter_gradient(x);
        ASSERT_EQ(gp.size(), flat.size());
        for (Index j = 0; j < flat.size(); ++j) {
            VectorXd plus = flat, minus = flat;
            plus[j] += h;
            minus[j] -= h;
            const double fd = (CellSDF(g, CellParameters::unflatten(plus, n, m)).value(x)
                                  - CellSDF(g, CellParameters::unflatten(minus, n, m)).value(x))
                / (2 * h);
            EXPECT_NEAR(fd, gp[j], 1e-7) << "x (" << x.transpose() << ") parameter " << j;
            checked += std::abs(gp[j]) > 1e-3;
        }
    }
    EXPECT_GT(checked, 100); // the derivatives checked are not all zero
}
