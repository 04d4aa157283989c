// The tiling of a deformed periodic cell (forward/periodic/tiling.hpp): welded copies whose
// boundary is that of the union, positions that follow (I + G) L s, and the exact intersection
// test finding a crossing across the cell's boundary that the cell alone cannot show.

#include "forward/contact/collision_mesh.hpp"
#include "forward/contact/intersection.hpp"
#include "forward/mesh/gmsh_reader.hpp"
#include "forward/periodic/tiling.hpp"

#include <gtest/gtest.h>

using namespace diffipc;

namespace {

PeriodicBox box_of(const Mesh& m)
{
    PeriodicBox box;
    box.lower = m.rest_positions.colwise().minCoeff().transpose();
    box.upper = m.rest_positions.colwise().maxCoeff().transpose();
    return box;
}

CollisionMesh surface(const Mesh& m) { return build_collision_mesh(m, { 1 }, { 0 }); }

} // namespace

TEST(Tiling, CopiesAreWeldedAndFollowTheMacroGradient)
{
    Mesh m = box_mesh(2, VectorXd::Zero(2), (VectorXd(2) << 1.5, 1).finished(), (VectorXi(2) << 3, 2).finished());
    compute_boundary(m);
    const PeriodicBox box = box_of(m);
    const PeriodicPairing p = pair_periodic_vertices(m, box, 1e-9, "mesh");
    const VectorXd G = (VectorXd(4) << -0.2, 0.1, 0.05, 0.3).finished();
    Eigen::Matrix2d F = Eigen::Matrix2d::Identity();
    F << 1 + G[0], G[1], G[2], 1 + G[3];
    VectorXd x(m.num_dofs());
    for (Index v = 0; v < m.num_vertices(); ++v)
        x.segment<2>(v * 2) = F * m.rest_positions.row(v).transpose();
    const Tiling t = tile_cell(m, box, p, x, G, 1);
    EXPECT_EQ(t.mesh.num_vertices(), 10 * 7); // a 9 x 6 grid of cells
    EXPECT_EQ(t.mesh.num_elements(), 9 * m.num_elements());
    EXPECT_EQ(t.mesh.boundary_facets.rows(), 2 * (9 + 6)); // the union's outline only
    for (Index v = 0; v < t.mesh.num_vertices(); ++v) {
        const Eigen::Vector2d X = t.mesh.rest_positions.row(v).transpose();
        EXPECT_LE((t.positions.row(v).transpose() - F * X).lpNorm<Eigen::Infinity>(), 1e-14) << v;
    }
    EXPECT_EQ(count_inverted_elements(t.mesh, t.positions), 0);
}

TEST(Tiling, ACrossingAcrossTheCellBoundaryIsFoundOnTheTiling)
{
    // The gmsh cell with a hole: at rest its tiling is intersection-free. Pull a vertex of the
    // hole's right side to x = 1.3, into the right neighbour's hole wall (at x = 1.2): the cell
    // alone (its periodic faces are no boundary) shows no crossing, its tiling does.
    Mesh m = read_gmsh(std::string(DIFFIPC_SOURCE_DIR) + "/tests/data/periodic/square_hole.msh", 2);
    const PeriodicBox box = box_of(m);
    const PeriodicPairing p = pair_periodic_vertices(m, box, 1e-9, "mesh");
    compute_boundary(m);
    remove_periodic_facets(m, box, 1e-9);
    VectorXd x = flatten(m.rest_positions);
    const VectorXd G = VectorXd::Zero(4);
    const Tiling rest = tile_cell(m, box, p, x, G, 1);
    EXPECT_EQ(find_intersection(surface(rest.mesh), rest.positions, true), "");
    Index right = -1;
    for (Index v = 0; v < m.num_vertices(); ++v)
        if (std::abs((m.rest_positions.row(v) - Eigen::RowVector2d(0.8, 0.5)).norm()) < 0.05)
            right = v;
    ASSERT_GE(right, 0) << "no hole vertex near (0.8, 0.5)";
    x[right * 2] = 1.3;
    EXPECT_EQ(find_intersection(surface(m), unflatten(x, 2), true), "");
    const Tiling moved = tile_cell(m, box, p, x, G, 1);
    EXPECT_NE(find_intersection(surface(moved.mesh), moved.positions, true), "");
}
