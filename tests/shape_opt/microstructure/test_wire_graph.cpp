// Wire graphs of microstructure cells (shape_opt/microstructure/wire_graph.hpp): OBJ `v` and `l`
// records, polylines split into edges, relative indices, `.wire` patterns in [0, 1]^2 rescaled,
// and errors naming the file and line.

#include "shape_opt/microstructure/wire_graph.hpp"

#include "forward/common/error.hpp"

#include <gtest/gtest.h>

using namespace diffipc;

namespace {

std::string message(const std::string& text)
{
    try {
        parse_wire_graph(text, "cell.obj");
    } catch (const InputError& e) {
        return e.what();
    }
    return "no error";
}

} // namespace

TEST(WireGraph, NodesAndPolylineEdgesAreRead)
{
    // A square grid's cross: four nodes on the faces, one at the centre; "l" polylines.
    const WireGraph g
        = parse_wire_graph("# cross\nv -1 0 0\nv 0 0\nv 1 0\nv 0 -1\nv 0 1 0.5\nl 1 2 3\nl -2 2 -1\n", "cell.obj");
    ASSERT_EQ(g.nodes.rows(), 5);
    EXPECT_DOUBLE_EQ(g.nodes(4, 1), 1.0);
    ASSERT_EQ(g.edges.rows(), 4);
    const int expected[4][2] = { { 0, 1 }, { 1, 2 }, { 3, 1 }, { 1, 4 } };
    for (int e = 0; e < 4; ++e)
        for (int k = 0; k < 2; ++k)
            EXPECT_EQ(g.edges(e, k), expected[e][k]) << "edge " << e;
}

TEST(WireGraph, BadRecordsAreErrorsNamingTheFileAndLine)
{
    EXPECT_EQ(message("v 0 0\nv 0.5 x\n"), "cell.obj: line 2: expected \"v x y [z]\" with finite coordinates");
    EXPECT_EQ(message("v 0 0\nv 1.5 0\n"), "cell.obj: line 2: node (1.5, 0) lies outside the cell [-1, 1]^2");
    EXPECT_EQ(message("v 0 0\nv 1 0\nl 1 3\n"), "cell.obj: line 3: node index 3 out of range (2 nodes)");
    EXPECT_EQ(message("v 0 0\nv 1 0\nl 1 1\n"), "cell.obj: line 3: an edge from node 1 to itself");
    EXPECT_EQ(message("v 0 0\nl 1\n"), "cell.obj: line 2: a line needs at least two node indices");
    EXPECT_EQ(message("v 0 0\nv 1 0\nl 1 b\n"), "cell.obj: line 3: expected node indices after \"l\", got \"b\"");
    EXPECT_EQ(message("v 0 0\nv 1 0\n"), "cell.obj: no edge (\"l\" records): a wire graph needs at least one");
    EXPECT_EQ(message("v 0 0\nv 1 0\nl -3 1\n"), "cell.obj: line 3: node index -3 out of range (2 nodes)");
}

TEST(WireGraph, WireFilesOfPatternLibrariesAreRescaledFromTheUnitCell)
{
    // A .wire pattern (PyMesh's wire networks: "v x y [z [w]]", "l i j"), nodes in [0, 1]^2: the
    // square grid's cross, as square_grid.obj writes it in [-1, 1]^2, one node with a
    // homogeneous w = 2 and all in the plane z = 0.
    const WireGraph g
        = parse_wire_graph("v 0 0.5 0\nv 0.5 0.5 0\nv 1 0.5 0\nv 0.5 0 0\nv 1 2 0 2\nl 1 2\nl 2 3\nl 4 2\nl 2 5\n",
            "cross.wire", WireGraphFormat::WIRE);
    const double expected[5][2] = { { -1, 0 }, { 0, 0 }, { 1, 0 }, { 0, -1 }, { 0, 1 } };
    ASSERT_EQ(g.nodes.rows(), 5);
    for (int v = 0; v < 5; ++v)
        for (int k = 0; k < 2; ++k)
            EXPECT_EQ(g.nodes(v, k), expected[v][k]) << "node " << v;
    ASSERT_EQ(g.edges.rows(), 4);
    EXPECT_EQ(g.edges(3, 0), 1);
    EXPECT_EQ(g.edges(3, 1), 4);
    EXPECT_EQ(g.file, "cross.wire");
    // 2D records without z are read too.
    EXPECT_EQ(parse_wire_graph("v 0 0.5\nv 1 0.5\nl 1 2\n", "p.wire", WireGraphFormat::WIRE).nodes(1, 0), 1.0);
    EXPECT_EQ(wire_graph_format("lib/pattern0646.wire"), WireGraphFormat::WIRE);
    EXPECT_EQ(wire_graph_format("cell.obj"), WireGraphFormat::OBJ);
}

TEST(WireGraph, TheExtensionIsReadWhateverItsCase)
{
    EXPECT_EQ(wire_graph_format("lib/PATTERN0646.WIRE"), WireGraphFormat::WIRE);
    EXPECT_EQ(wire_graph_format("lib/pattern.Wire"), WireGraphFormat::WIRE);
    EXPECT_EQ(wire_graph_format("CELL.OBJ"), WireGraphFormat::OBJ);
    EXPECT_EQ(wire_graph_format("cell.Obj"), WireGraphFormat::OBJ);
}

TEST(WireGraph, AWireFileMixingNodesWithAndWithoutZIsRefusedNamingTheLine)
{
    auto wire_message = [](const std::string& text) {
        try {
            parse_wire_graph(text, "p.wire", WireGraphFormat::WIRE);
        } catch (const InputError& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    EXPECT_EQ(wire_message("v 0 0.5\nv 1 0.5 0\nl 1 2\n"),
        "p.wire: line 2: \"v x y z\" after \"v x y\" on line 1: give every node of a .wire file a z, or none");
    EXPECT_EQ(wire_message("# z first\nv 0 0.5 0.2\nv 0.5 0.5 0.2\nv 1 0.5\nl 1 2 3\n"),
        "p.wire: line 4: \"v x y\" after \"v x y z\" on line 2: give every node of a .wire file a z, or none");
}

TEST(WireGraph, WireFilesThatCannotBeReadSayHow)
{
    auto wire_message = [](const std::string& text) {
        try {
            parse_wire_graph(text, "p.wire", WireGraphFormat::WIRE);
        } catch (const InputError& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    // Nodes in [-1, 1]^2 (an OBJ graph named .wire): the message says to name it .obj.
    const std::string outside = wire_message("v -1 0\nv 1 0\nl 1 2\n");
    EXPECT_EQ(outside.rfind("p.wire: line 1: node (-1, 0) lies outside the unit cell [0, 1]^2", 0), 0u) << outside;
    EXPECT_NE(outside.find("give it the extension .obj"), std::string::npos) << outside;
    // A 3D pattern.
    const std::string spatial = wire_message("v 0 0 0\nv 1 0 0\nv 1 1 1\nl 1 2\n");
    EXPECT_NE(spatial.find("p.wire: line 3: z = 1 differs from line 1's z = 0: a 3D pattern"), std::string::npos)
        << spatial;
    EXPECT_EQ(wire_message("v 0 0 0 0\nv 1 0\nl 1 2\n"),
        "p.wire: line 1: expected a finite, non-zero homogeneous coordinate w");
    // The same text as OBJ keeps OBJ's reading: z ignored, [-1, 1]^2.
    EXPECT_EQ(parse_wire_graph("v -1 0 0\nv 1 0 1\nl 1 2\n", "p.obj").nodes(0, 0), -1.0);
}
