// A pad tiled from a periodic cell (shape_opt/microstructure/cell_tiling.hpp): the copies' shared
// vertices are welded and no others (checked by an independent search for coincident vertices),
// the pad's area is the copies', its boundary is the cells' contour plus the pad's outer sides
// (no seam left open), its positions follow a moved cell mesh, the pullback is the transpose of
// that map, and a cell mesh that is not periodic is an input error.

#include "shape_opt/microstructure/cell_tiling.hpp"

#include "forward/common/error.hpp"
#include "shape_opt/microstructure/cell_mesher.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

using namespace diffipc;

namespace {

const std::string kTopologies = std::string(DIFFIPC_SOURCE_DIR) + "/shape_opt/microstructure/topologies/";

double area(const Positions& X, const MatrixXi& T)
{
    double a = 0;
    for (Index e = 0; e < T.rows(); ++e)
        a += signed_volume(X, T, e);
    return a;
}

} // namespace

TEST(CellTiling, WeldsTheCopiesSharedVerticesAndNoOthers)
{
    const CellFamily f = read_cell_family(kTopologies + "reentrant.json");
    VectorXd p = f.initial();
    p[f.width_index()] = 1.2;
    CellMeshSettings s;
    s.height = 0.01;
    s.size = 0.01 * 0.05;
    const Mesh cell = mesh_design(f, p, s);
    const int nx = 3, ny = 2;
    const CellTiling tiling(cell, 1.2, 0.01, nx, ny);
    const Mesh& pad = tiling.mesh();
    // every copy's vertex, its position computed here; coincident ones counted by sorting
    std::vector<std::pair<double, double>> all;
    for (int i = 0; i < nx; ++i)
        for (int j = 0; j < ny; ++j)
            for (Index v = 0; v < cell.num_vertices(); ++v)
                all.emplace_back(
                    cell.rest_positions(v, 0) + (i + 0.5) * 0.012, cell.rest_positions(v, 1) + (j + 0.5) * 0.01);
    std::sort(all.begin(), all.end());
    size_t distinct = 0;
    for (size_t k = 0; k < all.size(); ++k) {
        bool seen = false;
        for (size_t m = k; m-- > 0 && all[k].first - all[m].first < 1e-12;)
            seen = seen || std::abs(all[k].second - all[m].second) < 1e-12;
        distinct += !seen;
    }
    EXPECT_EQ(size_t(pad.num_vertices()), distinct);
    EXPECT_LT(pad.num_vertices(), nx * ny * cell.num_vertices());
    // no two pad vertices coincide
    std::vector<std::pair<double, double>> v;
    for (Index a = 0; a < pad.num_vertices(); ++a)
        v.emplace_back(pad.rest_positions(a, 0), pad.rest_positions(a, 1));
    std::sort(v.begin(), v.end());
    for (size_t k = 1; k < v.size(); ++k)
        for (size_t m = k; m-- > 0 && v[k].first - v[m].first < 1e-12;)
            EXPECT_GT(std::abs(v[k].second - v[m].second), 1e-12) << "vertices " << m << " and " << k;
    EXPECT_NEAR(area(pad.rest_positions, pad.elements), nx * ny * area(cell.rest_positions, cell.elements), 1e-15);
    for (Index e = 0; e < pad.num_elements(); ++e)
        EXPECT_GT(signed_volume(pad.rest_positions, pad.elements, e), 0);
    // The boundary: the cells' contour (their boundary edges off the box's sides) in each copy,
    // plus edges on the pad's own sides; no boundary edge lies on an inner seam.
    Index contour = 0;
    const double w = 0.012, h = 0.01;
    auto on_side = [](double c, double side) { return std::abs(c - side) < 1e-12; };
    for (Index e = 0; e < cell.boundary_facets.rows(); ++e) {
        const auto a = cell.rest_positions.row(cell.boundary_facets(e, 0)),
                   b = cell.rest_positions.row(cell.boundary_facets(e, 1));
        bool side = false;
        for (double x : { -w / 2, w / 2 })
            side = side || (on_side(a[0], x) && on_side(b[0], x));
        for (double y : { -h / 2, h / 2 })
            side = side || (on_side(a[1], y) && on_side(b[1], y));
        contour += !side;
    }
    Index outer = 0, seam = 0;
    for (Index e = 0; e < pad.boundary_facets.rows(); ++e) {
        const auto a = pad.rest_positions.row(pad.boundary_facets(e, 0)),
                   b = pad.rest_positions.row(pad.boundary_facets(e, 1));
        bool o = false, inner = false;
        for (int i = 0; i <= nx; ++i) {
            const bool along = on_side(a[0], i * w) && on_side(b[0], i * w);
            (i == 0 || i == nx ? o : inner) |= along;
        }
        for (int j = 0; j <= ny; ++j) {
            const bool along = on_side(a[1], j * h) && on_side(b[1], j * h);
            (j == 0 || j == ny ? o : inner) |= along;
        }
        outer += o;
        seam += inner && !o;
    }
    EXPECT_EQ(seam, 0);
    EXPECT_GT(outer, 0);
    EXPECT_EQ(pad.boundary_facets.rows(), nx * ny * contour + outer);
}

TEST(CellTiling, FollowsAMovedCellAndPullsBackByTheTranspose)
{
    const CellFamily f = read_cell_family(kTopologies + "diamond.json");
    CellMeshSettings s;
    s.size = 0.05;
    const Mesh cell = mesh_design(f, f.initial(), s);
    const CellTiling tiling(cell, 1.0, 1.0, 2, 3);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    Positions moved = cell.rest_positions;
    for (Index v = 0; v < moved.rows(); ++v)
        for (int a = 0; a < 2; ++a)
            moved(v, a) += 1e-3 * u(rng);
    const Positions X = tiling.positions(moved, 1.1);
    for (Index v = 0; v < X.rows(); ++v) { // each pad vertex is its source's moved position plus a lattice shift
        const Index c = tiling.source()[size_t(v)];
        const double sx = (X(v, 0) - moved(c, 0)) / 1.1 - 0.5, sy = X(v, 1) - moved(c, 1) - 0.5;
        EXPECT_NEAR(sx, std::round(sx), 1e-12);
        EXPECT_NEAR(sy, std::round(sy), 1e-12);
    }
    VectorXd g(X.size()), d(moved.size());
    for (Index k = 0; k < g.size(); ++k)
        g[k] = u(rng);
    for (Index k = 0; k < d.size(); ++k)
        d[k] = u(rng);
    Positions shifted = moved;
    shifted += Eigen::Map<const Positions>(d.data(), moved.rows(), 2);
    const VectorXd change = flatten(tiling.positions(shifted, 1.1)) - flatten(X);
    EXPECT_NEAR(g.dot(change), tiling.pullback(g).dot(d), 1e-12 * g.size());
}

TEST(CellTiling, ACellMeshThatIsNotPeriodicIsAnInputError)
{
    const CellFamily f = read_cell_family(kTopologies + "diamond.json");
    CellMeshSettings s;
    s.size = 0.05;
    Mesh cell = mesh_design(f, f.initial(), s);
    for (Index v = 0; v < cell.num_vertices(); ++v)
        if (std::abs(cell.rest_positions(v, 0) - 0.5) < 1e-12 && std::abs(cell.rest_positions(v, 1)) < 0.45) {
            cell.rest_positions(v, 1) += 1e-4; // a right side's vertex off its left partner
            break;
        }
    try {
        CellTiling(cell, 1.0, 1.0, 2, 2);
        FAIL() << "no error";
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), "cell mesh");
        EXPECT_NE(std::string(e.what()).find("no partner"), std::string::npos) << e.what();
    }
}
