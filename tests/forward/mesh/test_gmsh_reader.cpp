#include "forward/common/error.hpp"
#include "forward/mesh/gmsh_reader.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>

using namespace diffipc;

namespace {

std::string write_temp(const std::string& name, const std::string& text)
{
    const std::string path = testing::TempDir() + name;
    std::ofstream(path) << text;
    return path;
}

// One unit cube corner tetrahedron plus a point and a line element that must be skipped;
// node tags are not contiguous.
const char* V2 = R"($MeshFormat
2.2 0 8
$EndMeshFormat
$PhysicalNames
1
3 1 "solid"
$EndPhysicalNames
$Nodes
5
10 0 0 0
20 1 0 0
30 0 1 0
40 0 0 1
50 5 5 5
$EndNodes
$Elements
3
1 15 2 0 1 10
2 1 2 0 1 10 20
3 4 2 1 1 10 20 30 40
$EndElements
)";

const char* V4 = R"($MeshFormat
4.1 0 8
$EndMeshFormat
$Nodes
2 4 1 4
2 1 0 3
1
2
3
0 0 0
1 0 0
0 1 0
2 2 0 1
4
1 1 0
$EndNodes
$Elements
2 3 1 3
1 1 1 1
1 1 2
2 1 2 2
2 1 2 3
3 2 4 3
$EndElements
)";

TEST(GmshReader, ReadsVersion2Tetrahedra)
{
    const Mesh m = read_gmsh(write_temp("v2.msh", V2), 3);
    EXPECT_EQ(m.num_vertices(), 4); // the unused node 50 is dropped
    EXPECT_EQ(m.num_elements(), 1);
    EXPECT_NEAR(signed_volume(m.rest_positions, m.elements, 0), 1.0 / 6.0, 1e-15);
    EXPECT_EQ(m.boundary_facets.rows(), 4);
}

TEST(GmshReader, ReadsVersion4Triangles)
{
    const Mesh m = read_gmsh(write_temp("v4.msh", V4), 2);
    EXPECT_EQ(m.num_vertices(), 4);
    EXPECT_EQ(m.num_elements(), 2);
    EXPECT_NEAR(
        signed_volume(m.rest_positions, m.elements, 0) + signed_volume(m.rest_positions, m.elements, 1), 1.0, 1e-15);
    EXPECT_EQ(m.boundary_facets.rows(), 4);
}

TEST(GmshReader, ErrorsNameTheFile)
{
    const std::string missing = testing::TempDir() + "does_not_exist.msh";
    try {
        read_gmsh(missing, 3);
        FAIL();
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), missing);
    }
    EXPECT_THROW(read_gmsh(write_temp("binary.msh", "$MeshFormat\n4.1 1 8\n$EndMeshFormat\n"), 3), InputError);
    EXPECT_THROW(read_gmsh(write_temp("v3.msh", "$MeshFormat\n3.0 0 8\n$EndMeshFormat\n"), 3), InputError);
    EXPECT_THROW(read_gmsh(write_temp("empty.msh", "hello\n"), 3), InputError);
    // No tetrahedra in a triangle-only file.
    EXPECT_THROW(read_gmsh(write_temp("v4b.msh", V4), 3), InputError);
    // Truncated node section.
    EXPECT_THROW(read_gmsh(write_temp("trunc.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n"), 3),
        InputError);
    // Element referring to an undefined node.
    std::string bad = V2;
    bad.replace(bad.find("10 20 30 40"), 11, "10 20 30 99");
    EXPECT_THROW(read_gmsh(write_temp("undef.msh", bad), 3), InputError);
    // Garbage in a number.
    std::string garbage = V2;
    garbage.replace(garbage.find("20 1 0 0"), 8, "20 1 x 0");
    EXPECT_THROW(read_gmsh(write_temp("garbage.msh", garbage), 3), InputError);
    // Node block counts of -1 and 2^62 (before: a vector of that size, bad_alloc or
    // length_error, exit 3): an InputError naming the file, allocating nothing.
    for (const char* count : { "-1", "4611686018427387904" }) {
        std::string v4 = V4;
        v4.replace(v4.find("2 1 0 3"), 7, std::string("2 1 0 ") + count);
        const std::string path = write_temp(std::string("count") + count + ".msh", v4);
        try {
            read_gmsh(path, 2);
            FAIL() << count;
        } catch (const InputError& e) {
            EXPECT_EQ(e.field(), path) << e.what();
        }
    }
}

} // namespace
