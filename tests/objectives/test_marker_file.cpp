// objectives/marker_file.hpp: marker files read and attached to a mesh. Attached points are
// checked by rebuilding their positions from the weights (sum_a w_a X_a), not by the reader's
// own search; bad files must fail with the file and line named.

#include "objectives/marker_file.hpp"

#include "forward/common/error.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include <unistd.h>

using namespace diffipc;

namespace {

std::string write_file(const std::string& name, const std::string& text)
{
    const std::string path
        = (std::filesystem::temp_directory_path() / ("diffipc_markers_" + std::to_string(::getpid()) + "_" + name))
              .string();
    std::ofstream(path) << text;
    return path;
}

/// The unit square in 4 x 4 cells (vertices every 0.25 m).
Mesh square() { return box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1), Eigen::Vector2i(4, 4)); }

VectorXd position(const Mesh& mesh, const MarkerPoint& p)
{
    VectorXd x = VectorXd::Zero(mesh.dim);
    for (size_t a = 0; a < p.vertices.size(); ++a)
        x += p.weights[a] * mesh.rest_positions.row(p.vertices[a]).transpose();
    return x;
}

std::string error_of(const std::string& path, const Mesh& mesh, double dt = 0.1, int steps = 10)
{
    try {
        read_marker_file(path, mesh, mesh.rest_positions, mesh.num_vertices(), dt, steps, 0);
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

} // namespace

TEST(MarkerFile, VerticesAndInteriorPointsOfAStaticFile)
{
    const Mesh mesh = square();
    // A vertex (0.25, 0.5) off by 1e-9 (within the default tolerance, 1e-6 of the diagonal),
    // an interior point, a point on an edge between two cells; commas and a comment.
    const std::string path = write_file("static.txt",
        "# rest x, y   measured x, y\n"
        "0.25 0.500000001   0.26 0.49\n"
        "0.3, 0.7, 0.31, 0.69\n"
        "\n"
        "0.5 0.125 0.52 0.12  # on the vertical line x = 0.5\n");
    const MarkerData data = read_marker_file(path, mesh, mesh.rest_positions, mesh.num_vertices(), 0.1, 10, 0);
    ASSERT_EQ(data.markers.size(), 3u);
    EXPECT_EQ(data.at_vertices, 1);
    ASSERT_EQ(data.markers[0].vertices.size(), 1u);
    EXPECT_LT((mesh.rest_positions.row(data.markers[0].vertices[0]) - Eigen::RowVector2d(0.25, 0.5)).norm(), 1e-15);
    EXPECT_LT((position(mesh, data.markers[1]) - Eigen::Vector2d(0.3, 0.7)).norm(), 1e-14);
    EXPECT_LT((position(mesh, data.markers[2]) - Eigen::Vector2d(0.5, 0.125)).norm(), 1e-14);
    for (size_t m = 1; m < 3; ++m)
        for (double w : data.markers[m].weights)
            EXPECT_GE(w, 0.0);
    EXPECT_TRUE(data.steps.empty()); // a static file: the caller picks the step
    ASSERT_EQ(data.targets.size(), 1u);
    EXPECT_EQ(data.targets[0](1, 0), 0.31);
    EXPECT_EQ(data.targets[0](2, 1), 0.12);
    std::remove(path.c_str());
}

TEST(MarkerFile, ATimeColumnGivesTheSteps)
{
    const Mesh mesh = square();
    const std::string path = write_file("transient.txt",
        "0.3 0.7  0.2  0.31 0.70\n"
        "0.6 0.6  0.2  0.61 0.60\n"
        "0.6 0.6  0.5  0.62 0.60\n"
        "0.3 0.7  0.5  0.32 0.70\n");
    const MarkerData data = read_marker_file(path, mesh, mesh.rest_positions, mesh.num_vertices(), 0.1, 10, 0);
    ASSERT_EQ(data.steps, (std::vector<int> { 2, 5 }));
    ASSERT_EQ(data.targets.size(), 2u);
    EXPECT_EQ(data.targets[1](0, 0), 0.32); // marker 0 is (0.3, 0.7), whatever the row order
    EXPECT_EQ(data.targets[1](1, 0), 0.62);
    std::remove(path.c_str());
    // A time between steps, and a marker missing at one time.
    const std::string off = write_file("off.txt", "0.3 0.7 0.25 0.31 0.7\n");
    EXPECT_NE(error_of(off, mesh).find("off.txt:1"), std::string::npos) << error_of(off, mesh);
    EXPECT_NE(error_of(off, mesh).find("not a step"), std::string::npos);
    const std::string missing
        = write_file("missing.txt", "0.3 0.7 0.2 0.31 0.7\n0.6 0.6 0.2 0.6 0.6\n0.3 0.7 0.5 0.3 0.7\n");
    EXPECT_NE(error_of(missing, mesh).find("no row at time 0.5"), std::string::npos) << error_of(missing, mesh);
    std::remove(off.c_str());
    std::remove(missing.c_str());
}

TEST(MarkerFile, BadFilesNameTheFileAndLine)
{
    const Mesh mesh = square();
    const auto check = [&](const std::string& name, const std::string& text, const std::string& expected) {
        const std::string path = write_file(name, text);
        const std::string error = error_of(path, mesh);
        EXPECT_NE(error.find(name), std::string::npos) << error;
        EXPECT_NE(error.find(expected), std::string::npos) << name << ": " << error;
        std::remove(path.c_str());
    };
    check("word.txt", "0.3 0.7 0.31 0.69\n0.3 0.7 abc 0.69\n", ":2");
    check("nan.txt", "0.3 0.7 nan 0.69\n", "non-finite");
    check("count.txt", "0.3 0.7 0.31\n", "expected 4 numbers");
    check("mixed.txt", "0.3 0.7 0.31 0.69\n0.4 0.7 0.1 0.41 0.69\n", "every row of a file has the same form");
    check("empty.txt", "# nothing\n", "no marker rows");
    check("twice.txt", "0.3 0.7 0.31 0.69\n0.3 0.7 0.32 0.69\n", "repeats the rest position");
    // Millimetres by mistake: far outside the mesh's box.
    check("mm.txt", "300 700 310 690\n", "millimetres");
}

TEST(MarkerFile, APointOutsideTheMeshIsRefused)
{
    // An annulus: its centre is inside the bounding box but in no element.
    const Mesh ring = annulus_mesh(Eigen::Vector2d(0, 0), 0.5, 1.0, 32, 2);
    const std::string path = write_file("hole.txt", "0.0 0.05 0.0 0.05\n");
    const std::string error = error_of(path, ring);
    EXPECT_NE(error.find("hole.txt:1"), std::string::npos) << error;
    EXPECT_NE(error.find("outside the mesh"), std::string::npos) << error;
    std::remove(path.c_str());
    EXPECT_NE(error_of("/nonexistent/markers.txt", ring).find("cannot open"), std::string::npos);
}

TEST(MarkerFile, ThreeDimensionalMarkersOnAFaceOfABox)
{
    const Mesh box = box_mesh(3, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 1), Eigen::Vector3i(2, 2, 2));
    // On the face x = 1: a vertex, and a point inside a face triangle.
    const std::string path = write_file("box.txt", "1 0.5 0.5  1.01 0.5 0.5\n1 0.3 0.6  1.01 0.3 0.6\n");
    const MarkerData data = read_marker_file(path, box, box.rest_positions, box.num_vertices(), 1, 1, 0);
    EXPECT_EQ(data.at_vertices, 1);
    EXPECT_LT((position(box, data.markers[1]) - Eigen::Vector3d(1, 0.3, 0.6)).norm(), 1e-14);
    std::remove(path.c_str());
}

TEST(MarkerFile, AMarkerJustOutsideTheMeshNamesTheToleranceThatAttachesIt)
{
    // Scan data rounded to 10 um: a marker 6 um outside the edge x = 1, beside the vertex (1, 0.25).
    // Before, the error did not say which key fixes it.
    const Mesh mesh = square();
    const std::string path = write_file("rounded.txt", "1.000006 0.25  1.01 0.25\n");
    const std::string error = error_of(path, mesh);
    EXPECT_NE(error.find("rounded.txt:1"), std::string::npos) << error;
    EXPECT_NE(error.find("outside the mesh"), std::string::npos) << error;
    EXPECT_NE(error.find("\"vertex_tolerance\""), std::string::npos) << error;
    EXPECT_NE(error.find("6e-06 m away"), std::string::npos) << error;
    // The key, at the distance the message gives, attaches the marker to that vertex.
    const MarkerData data = read_marker_file(path, mesh, mesh.rest_positions, mesh.num_vertices(), 0.1, 10, 6.1e-6);
    ASSERT_EQ(data.markers.size(), 1u);
    EXPECT_EQ(data.at_vertices, 1);
    EXPECT_LT((position(mesh, data.markers[0]) - Eigen::Vector2d(1, 0.25)).norm(), 1e-15);
    std::remove(path.c_str());
}
