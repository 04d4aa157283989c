// Meshes of microstructure cells (shape_opt/microstructure/cell_mesher.hpp), checked by code
// independent of the mesher: positive elements, vertices on opposite sides that match one to
// one, boundary vertices on the level set, the mesh's area against the solid's area by
// sampling phi, designs at the family's bounds that mesh, and degenerate designs that are input
// errors naming what is wrong (a tiling that falls apart naming the graph file).

#include "shape_opt/microstructure/cell_mesher.hpp"

#include "forward/common/error.hpp"
#include "forward/common/union_find.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>

#include <unistd.h>

using namespace diffipc;

namespace {

const std::string kTopologies = std::string(DIFFIPC_SOURCE_DIR) + "/shape_opt/microstructure/topologies/";

double triangle_area(const Mesh& m, Index e)
{
    const Eigen::Vector2d a = m.rest_positions.row(m.elements(e, 0)).transpose();
    const Eigen::Vector2d b = m.rest_positions.row(m.elements(e, 1)).transpose();
    const Eigen::Vector2d c = m.rest_positions.row(m.elements(e, 2)).transpose();
    const Eigen::Vector2d u = b - a, v = c - a;
    return 0.5 * (u.x() * v.y() - u.y() * v.x());
}

/// Checks a cell mesh of `sdf` at `width`; returns its area.
double check_cell_mesh(const Mesh& m, const CellSDF& sdf, double width, const CellMeshSettings& s)
{
    double area = 0;
    for (Index e = 0; e < m.elements.rows(); ++e) {
        const double a = triangle_area(m, e);
        EXPECT_GT(a, 0) << "element " << e;
        area += a;
    }
    const Eigen::Vector2d lo = cell_box_min(width, s.height), hi = cell_box_max(width, s.height);
    const Eigen::Vector2d scale(0.5 * width * s.height, 0.5 * s.height);
    // Every vertex in the box; boundary vertices inside the box on phi = 0.
    std::vector<char> on_boundary(size_t(m.rest_positions.rows()), 0);
    for (Index f = 0; f < m.boundary_facets.rows(); ++f)
        on_boundary[size_t(m.boundary_facets(f, 0))] = on_boundary[size_t(m.boundary_facets(f, 1))] = 1;
    int on_contour = 0;
    for (Index v = 0; v < m.rest_positions.rows(); ++v) {
        const Eigen::Vector2d X = m.rest_positions.row(v).transpose();
        EXPECT_TRUE((X.array() >= lo.array() - 1e-12).all() && (X.array() <= hi.array() + 1e-12).all());
        const bool inside = (X.array() > lo.array() + 1e-12).all() && (X.array() < hi.array() - 1e-12).all();
        if (on_boundary[size_t(v)] && inside) {
            EXPECT_NEAR(sdf.value(X.cwiseQuotient(scale)), 0, 1e-10) << "vertex " << v;
            ++on_contour;
        }
    }
    EXPECT_GT(on_contour, 0);
    // Opposite sides: the same coordinates along the side, one to one.
    for (int axis = 0; axis < 2; ++axis) {
        std::multiset<double> low, high;
        for (Index v = 0; v < m.rest_positions.rows(); ++v) {
            if (m.rest_positions(v, axis) == lo[axis])
                low.insert(m.rest_positions(v, 1 - axis));
            if (m.rest_positions(v, axis) == hi[axis])
                high.insert(m.rest_positions(v, 1 - axis));
        }
        EXPECT_FALSE(low.empty());
        EXPECT_EQ(low, high) << "axis " << axis;
    }
    // The solid's area by sampling phi at 400,000 points of the R2 low-discrepancy sequence (a
    // regular grid aliases with beams at 45 degrees).
    const int n = 400000;
    int solid = 0;
    for (int k = 0; k < n; ++k) {
        const double u = std::fmod(0.5 + 0.7548776662466927 * k, 1.0), w = std::fmod(0.5 + 0.5698402909980532 * k, 1.0);
        solid += sdf.value(Eigen::Vector2d(2 * u - 1, 2 * w - 1)) < 0;
    }
    const double sampled = double(solid) / n * (hi - lo).prod();
    EXPECT_NEAR(area, sampled, 0.003 * sampled); // seen: at most 0.12%
    return area;
}

std::string error_field(const std::function<void()>& f)
{
    try {
        f();
    } catch (const InputError& e) {
        return e.field() + ": " + e.what();
    }
    return "(no error)";
}

} // namespace

TEST(CellMesher, EachTopologyMeshesPeriodicallyOnItsLevelSet)
{
    CellMeshSettings s;
    s.size = 0.03;
    for (const char* name : { "square_grid", "diamond", "diamond_stop", "reentrant", "curved_beam" }) {
        SCOPED_TRACE(name);
        const CellFamily f = read_cell_family(kTopologies + name + ".json");
        const VectorXd p = f.initial();
        const Mesh m = mesh_design(f, p, s);
        EXPECT_GT(m.elements.rows(), 100);
        check_cell_mesh(m, CellSDF(f.graph(), f.cell_parameters(p)), p[f.width_index()], s);
    }
}

TEST(CellMesher, DesignsAtTheBoundsMesh)
{
    // Every variable at its lower bound, at its upper bound, and alternating, per topology (the
    // mesh size below the thinnest beam at the narrowest width).
    CellMeshSettings s;
    s.size = 0.025;
    for (const char* name : { "square_grid", "diamond", "diamond_stop", "reentrant", "curved_beam" }) {
        const CellFamily f = read_cell_family(kTopologies + name + ".json");
        for (int corner = 0; corner < 4; ++corner) {
            SCOPED_TRACE(std::string(name) + " corner " + std::to_string(corner));
            VectorXd p = corner == 0 ? f.lower() : f.upper();
            for (Index v = 0; v < f.size() && corner >= 2; ++v)
                p[v] = (v + corner) % 2 ? f.lower()[v] : f.upper()[v];
            const Mesh m = mesh_design(f, p, s);
            check_cell_mesh(m, CellSDF(f.graph(), f.cell_parameters(p)), p[f.width_index()], s);
        }
    }
}

TEST(CellMesher, DegenerateDesignsAreInputErrors)
{
    CellMeshSettings s;
    s.size = 0.05;
    // A beam thinner than the mesh size: named by its variable.
    const CellFamily grid = read_cell_family(kTopologies + "square_grid.json");
    EXPECT_EQ(error_field([&] { mesh_design(grid, grid.lower(), s); }).substr(0, 20), "design.thickness[0]:");
    // Beyond the bounds.
    VectorXd p = grid.upper();
    p[grid.width_index()] += 0.1;
    EXPECT_EQ(error_field([&] { mesh_design(grid, p, s); }).substr(0, 13), "design.width:");
    // A short beam in the middle of the cell: it reaches no side.
    CellFamily::Settings settings;
    const CellFamily island(parse_wire_graph("v -0.3 0\nv 0.3 0\nl 1 2\n", "island.obj"), settings, "f");
    EXPECT_NE(error_field([&] { mesh_design(island, island.initial(), s); }).find("does not reach"), std::string::npos);
    // A beam across the cell and a loose one beside it: two pieces.
    const CellFamily loose(
        parse_wire_graph("v -1 0\nv 1 0\nv 0 -1\nv 0 1\nv 0.4 0.4\nv 0.6 0.6\nl 1 2\nl 3 4\nl 5 6\n", "loose.obj"),
        settings, "f");
    EXPECT_NE(
        error_field([&] { mesh_design(loose, loose.initial(), s); }).find("falls apart into 2"), std::string::npos)
        << error_field([&] { mesh_design(loose, loose.initial(), s); });
}

TEST(CellMesher, ATilingThatFallsApartIsRefusedNamingTheGraphFile)
{
    // One beam from the centre to a corner: glued to itself across the sides it is one piece
    // (the corner's four quarter disks are one disk on the torus), but its tiling is a set of
    // separate diagonal strokes. The error names the graph file, read from disk as a family's.
    const std::filesystem::path dir
        = std::filesystem::temp_directory_path() / ("diffipc_test_tiling_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    const std::string graph = (dir / "diagonal.obj").string();
    std::ofstream(graph) << "v 0 0\nv 1 1\nl 1 2\n";
    std::ofstream(dir / "diagonal.json") << "{\"graph\": \"diagonal.obj\"}\n";
    const CellFamily f = read_cell_family((dir / "diagonal.json").string());
    CellMeshSettings s;
    s.size = 0.03;
    const std::string error = error_field([&] { mesh_design(f, f.initial(), s); });
    std::filesystem::remove_all(dir);
    EXPECT_EQ(error.substr(0, graph.size() + 1), graph + ":") << error;
    EXPECT_NE(error.find("3 x 3 tiling is not one connected solid"), std::string::npos) << error;
}

TEST(CellMesher, ABeamEndingOnASideStillTiles)
{
    // A cross with a stub from the centre to the right side: the stub's end shows as a loose half
    // disk on the left side (its copy from the left neighbour), on the torus and in the tiling
    // joined to that neighbour's stub. The 3 x 3 block's leftmost copies keep such a bit on the
    // block's border, whose beam lies outside the block: accepted all the same.
    CellFamily::Settings settings;
    const CellFamily stub(
        parse_wire_graph("v -1 0\nv 1 0\nv 0 -1\nv 0 1\nv 0 0\nv 1 0.5\nl 1 2\nl 3 4\nl 5 6\n", "stub.obj"), settings,
        "f");
    CellMeshSettings s;
    s.size = 0.03;
    const Mesh m = mesh_design(stub, stub.initial(), s);
    check_cell_mesh(m, CellSDF(stub.graph(), stub.cell_parameters(stub.initial())), 1.0, s);
}

TEST(CellMesher, ABeamEndingOnTheLeftOrBottomSideStillTiles)
{
    // The mirror of the above: a stub to the left (bottom) side leaves its loose cap on the right
    // (top) side, so the right (top) neighbour in the 3 x 3 block holds a bit on the block's border
    // whose beam lies outside the block: accepted, whichever element gmsh numbers first (the next
    // test puts one of the cap first).
    CellFamily::Settings settings;
    CellMeshSettings s;
    s.size = 0.03;
    for (const char* end : { "v -1 0.5", "v 0.5 -1", "v -1 -0.5", "v -0.5 -1" }) {
        const CellFamily stub(
            parse_wire_graph(
                "v -1 0\nv 1 0\nv 0 -1\nv 0 1\nv 0 0\n" + std::string(end) + "\nl 1 2\nl 3 4\nl 5 6\n", "stub.obj"),
            settings, "f");
        try {
            const Mesh m = mesh_design(stub, stub.initial(), s);
            check_cell_mesh(m, CellSDF(stub.graph(), stub.cell_parameters(stub.initial())), 1.0, s);
        } catch (const InputError& e) {
            ADD_FAILURE() << end << ": " << e.what();
        }
    }
}

TEST(CellMesher, TheTilingCheckDoesNotDependOnWhichElementComesFirst)
{
    // A stub to the left side: its cap is a loose bit on the right side. In the 3 x 3 block, the
    // right neighbour's cap belongs to a copy outside the block; with an element of that cap put
    // first (gmsh may number it so), the check still sees the neighbour joined to the middle copy.
    CellFamily::Settings settings;
    CellMeshSettings s;
    s.size = 0.03;
    for (const char* end : { "v -1 0.5", "v 0.5 -1" }) {
        const CellFamily stub(
            parse_wire_graph(
                "v -1 0\nv 1 0\nv 0 -1\nv 0 1\nv 0 0\n" + std::string(end) + "\nl 1 2\nl 3 4\nl 5 6\n", "stub.obj"),
            settings, "f");
        Mesh m = mesh_design(stub, stub.initial(), s);
        // The cell's pieces without gluing its sides: the cap is the smallest.
        UnionFind pieces(m.num_vertices());
        for (Index e = 0; e < m.num_elements(); ++e)
            for (int a = 1; a < 3; ++a)
                pieces.join(m.elements(e, 0), m.elements(e, a));
        std::map<Index, Index> size;
        for (Index e = 0; e < m.num_elements(); ++e)
            ++size[pieces.find(m.elements(e, 0))];
        ASSERT_EQ(size.size(), 2u) << end << ": the cross and the cap";
        const Index cap = size.begin()->second < size.rbegin()->second ? size.begin()->first : size.rbegin()->first;
        Index first = 0;
        while (pieces.find(m.elements(first, 0)) != cap)
            ++first;
        const Eigen::RowVectorXi swapped = m.elements.row(0);
        m.elements.row(0) = m.elements.row(first);
        m.elements.row(first) = swapped;
        EXPECT_NO_THROW(check_cell_tiling(m, 1.0, s.height, "stub.obj")) << end;
    }
}
