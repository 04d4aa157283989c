// Obstacle surface meshes: .obj and .msh, 2D and 3D, and their errors.

#include "forward/common/error.hpp"
#include "forward/mesh/mesh.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <string>

using namespace diffipc;

namespace {

std::string write_file(const std::string& name, const std::string& text)
{
    const std::string path = ::testing::TempDir() + name;
    std::ofstream(path) << text;
    return path;
}

std::string error_of(const std::string& path, int dim)
{
    try {
        read_surface_mesh(path, dim);
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

} // namespace

TEST(SurfaceReader, ObjTrianglesQuadsAndNegativeIndices)
{
    const std::string path = write_file("quad.obj",
        "# a unit square as one quad and a triangle by negative indices\n"
        "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nv 0 1 0\n"
        "f 1/1 2/2 3/3 4/4\nf -5 -4 -1\n");
    const Mesh m = read_surface_mesh(path, 3);
    EXPECT_EQ(m.num_vertices(), 5);
    EXPECT_EQ(m.num_elements(), 0);
    ASSERT_EQ(m.boundary_facets.rows(), 3); // the quad is fanned into two triangles
    EXPECT_EQ(m.boundary_facets(0, 0), 0);
    EXPECT_EQ(m.boundary_facets(1, 2), 3);
    EXPECT_EQ(m.boundary_facets(2, 2), 4);
}

TEST(SurfaceReader, ObjPolylineIn2D)
{
    const std::string path = write_file("line.obj", "v -1 0\nv 0 -0.1\nv 1 0\nl 1 2 3\n");
    const Mesh m = read_surface_mesh(path, 2);
    EXPECT_EQ(m.dim, 2);
    EXPECT_EQ(m.boundary_facets.rows(), 2);
    EXPECT_DOUBLE_EQ(m.rest_positions(1, 1), -0.1);
}

TEST(SurfaceReader, VerticesOnNoFacetAreDropped)
{
    // Before: kept as obstacle vertices (prescribed dofs in every state, frame and record), so a
    // 50 MB file of vertices with one face ran out of memory (std::bad_alloc, exit 3).
    const std::string path = write_file("stray.obj", "v 9 9 9\nv 0 0 0\nv 8 8 8\nv 1 0 0\nv 0 1 0\nv 7 7 7\nf 2 4 5\n");
    const Mesh m = read_surface_mesh(path, 3);
    ASSERT_EQ(m.num_vertices(), 3);
    ASSERT_EQ(m.boundary_facets.rows(), 1);
    EXPECT_EQ(m.vertex_body.size(), 3);
    for (int a = 0; a < 3; ++a)
        EXPECT_EQ(m.boundary_facets(0, a), a);
    EXPECT_EQ(m.rest_positions.row(1), Eigen::RowVector3d(1, 0, 0));
    EXPECT_EQ(m.rest_positions.row(2), Eigen::RowVector3d(0, 1, 0));
}

TEST(SurfaceReader, GmshTrianglesAndLines)
{
    const std::string path = write_file("surface.msh",
        "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 1 1 0\n4 0 1 0\n$EndNodes\n"
        "$Elements\n4\n1 1 2 0 1 1 2\n2 1 2 0 1 2 3\n3 2 2 0 1 1 2 3\n4 2 2 0 1 1 3 4\n$EndElements\n");
    const Mesh m3 = read_surface_mesh(path, 3);
    EXPECT_EQ(m3.boundary_facets.rows(), 2);
    EXPECT_EQ(m3.boundary_facets.cols(), 3);
    const Mesh m2 = read_surface_mesh(path, 2);
    EXPECT_EQ(m2.boundary_facets.rows(), 2);
    EXPECT_EQ(m2.boundary_facets.cols(), 2);
    EXPECT_EQ(m2.num_vertices(), 3); // node 4 is on no line
}

TEST(SurfaceReader, ErrorsNameTheFileAndLine)
{
    EXPECT_NE(error_of(write_file("bad1.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n"), 3).find("bad1.obj:4"),
        std::string::npos);
    EXPECT_NE(error_of(write_file("bad2.obj", "v 0 0 0\nv nan 0 0\n"), 3).find("bad2.obj:2"), std::string::npos);
    EXPECT_NE(error_of(write_file("bad3.obj", "v 0 0 0\n"), 3).find("no faces"), std::string::npos);
    EXPECT_NE(error_of(write_file("bad4.obj", "v 0 0 0\nv 0 0 0\nv 1 1 1\nf 1 2 2\n"), 3).find("degenerate"),
        std::string::npos);
    EXPECT_NE(error_of(write_file("bad5.stl", "solid\n"), 3).find("unsupported"), std::string::npos);
}
