// Wire graphs of microstructure cells (shape_opt/microstructure/wire_graph.hpp): OBJ `v` and `l`
// records, polylines split into edges, relative indices, and errors naming the file and line.

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
