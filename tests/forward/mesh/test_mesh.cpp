#include "forward/common/error.hpp"
#include "forward/mesh/mesh.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <map>

using namespace diffipc;

namespace {

// Divergence theorem on the boundary: sum over facets of (centroid . n) |f| = dim * volume,
// and the facet normals sum to zero for a closed boundary.
void check_closed_boundary(const Mesh& mesh, double volume)
{
    const int d = mesh.dim;
    double flux = 0;
    Eigen::Vector3d normal_sum = Eigen::Vector3d::Zero();
    for (Index f = 0; f < mesh.boundary_facets.rows(); ++f) {
        Eigen::Vector3d p[3];
        for (int a = 0; a < d; ++a) {
            p[a].setZero();
            p[a].head(d) = mesh.rest_positions.row(mesh.boundary_facets(f, a)).transpose();
        }
        Eigen::Vector3d area_normal, centroid;
        if (d == 2) {
            const Eigen::Vector3d t = p[1] - p[0];
            area_normal = Eigen::Vector3d(t[1], -t[0], 0); // right of the edge: outward for CCW
            centroid = 0.5 * (p[0] + p[1]);
        } else {
            area_normal = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]);
            centroid = (p[0] + p[1] + p[2]) / 3.0;
        }
        flux += centroid.dot(area_normal);
        normal_sum += area_normal;
    }
    EXPECT_NEAR(flux, d * volume, 1e-12 * volume);
    EXPECT_LT(normal_sum.norm(), 1e-12);
}

TEST(BoxMesh, TrianglesArePositiveAndTileTheBox)
{
    const Mesh m = box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(2, 1), Eigen::Vector2i(4, 3));
    EXPECT_EQ(m.num_vertices(), 20);
    EXPECT_EQ(m.num_elements(), 24);
    double total = 0;
    for (Index e = 0; e < m.num_elements(); ++e) {
        const double v = signed_volume(m.rest_positions, m.elements, e);
        EXPECT_GT(v, 0);
        total += v;
    }
    EXPECT_NEAR(total, 2.0, 1e-14);
    EXPECT_EQ(m.boundary_facets.rows(), 2 * (4 + 3));
    check_closed_boundary(m, 2.0);
}

TEST(BoxMesh, TetrahedraArePositiveConformingAndTileTheBox)
{
    const Mesh m = box_mesh(3, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 2, 3), Eigen::Vector3i(2, 3, 4));
    EXPECT_EQ(m.num_elements(), 6 * 24);
    double total = 0;
    for (Index e = 0; e < m.num_elements(); ++e) {
        const double v = signed_volume(m.rest_positions, m.elements, e);
        EXPECT_GT(v, 0);
        total += v;
    }
    EXPECT_NEAR(total, 6.0, 1e-13);
    // Conforming: only the box surface is boundary, two triangles per face cell.
    EXPECT_EQ(m.boundary_facets.rows(), 2 * 2 * (2 * 3 + 3 * 4 + 2 * 4));
    check_closed_boundary(m, 6.0);
}

TEST(Mesh, AppendOffsetsIndicesAndBodies)
{
    Mesh all;
    const Mesh a = box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1), Eigen::Vector2i(1, 1));
    append_mesh(all, a, 0);
    append_mesh(all, a, 1);
    EXPECT_EQ(all.num_vertices(), 8);
    EXPECT_EQ(all.elements.maxCoeff(), 7);
    EXPECT_EQ(all.vertex_body[7], 1);
    EXPECT_EQ(all.facet_body[all.facet_body.size() - 1], 1);
}

TEST(Mesh, ValidationRejectsInvertedAndDegenerateElements)
{
    Mesh m = box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1), Eigen::Vector2i(2, 2));
    EXPECT_NO_THROW(validate_mesh(m, "mesh"));
    Mesh inverted = m;
    std::swap(inverted.elements(3, 1), inverted.elements(3, 2));
    EXPECT_THROW(validate_mesh(inverted, "bodies[0].mesh"), InputError);
    try {
        validate_mesh(inverted, "bodies[0].mesh");
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("element 3 is inverted"), std::string::npos) << e.what();
        EXPECT_EQ(e.field(), "bodies[0].mesh");
    }
    Mesh degenerate = m;
    degenerate.rest_positions.row(degenerate.elements(0, 2)) = degenerate.rest_positions.row(degenerate.elements(0, 0));
    EXPECT_THROW(validate_mesh(degenerate, "mesh"), InputError);
    Mesh nonfinite = m;
    nonfinite.rest_positions(0, 0) = std::nan("");
    EXPECT_THROW(validate_mesh(nonfinite, "mesh"), InputError);
}

} // namespace

TEST(MeshGenerators, AnnulusAreaOrientationAndBoundary)
{
    VectorXd c(2);
    c << 0.3, -0.2;
    const int N = 40;
    const Mesh m = annulus_mesh(c, 0.5, 0.8, N, 3);
    double area = 0;
    for (Index e = 0; e < m.num_elements(); ++e) {
        const double a = signed_volume(m.rest_positions, m.elements, e);
        EXPECT_GT(a, 0) << "element " << e;
        area += a;
    }
    // The polygonal annulus: N/2 sin(2 pi/N) (r1^2 - r0^2).
    EXPECT_NEAR(area, 0.5 * N * std::sin(2 * M_PI / N) * (0.64 - 0.25), 1e-12);
    EXPECT_EQ(m.boundary_facets.rows(), 2 * N); // inner and outer circles
}

TEST(MeshGenerators, TorusVolumeOrientationAndClosedSurface)
{
    const double R = 0.1, a = 0.02;
    const Mesh m = torus_mesh(R, a, 2, 48);
    double volume = 0;
    for (Index e = 0; e < m.num_elements(); ++e) {
        const double v = signed_volume(m.rest_positions, m.elements, e);
        EXPECT_GT(v, 0) << "element " << e;
        volume += v;
    }
    // Pappus: 2 pi R (2a)^2, less the faceting of the 48 segments (about 0.3%).
    EXPECT_NEAR(volume / (2 * M_PI * R * 4 * a * a), 1.0, 0.01);
    // Closed surface: 4 sides x 2 cells x 48 segments x 2 triangles, every edge shared by two faces.
    EXPECT_EQ(m.boundary_facets.rows(), 4 * 2 * 48 * 2);
    std::map<std::pair<int, int>, int> edges;
    for (Index f = 0; f < m.boundary_facets.rows(); ++f)
        for (int k = 0; k < 3; ++k) {
            const int u = m.boundary_facets(f, k), w = m.boundary_facets(f, (k + 1) % 3);
            ++edges[{ std::min(u, w), std::max(u, w) }];
        }
    for (const auto& [e, count] : edges)
        EXPECT_EQ(count, 2);
    EXPECT_EQ(m.num_vertices(), 3 * 3 * 48); // the seam is merged
}
