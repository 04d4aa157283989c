// Periodic meshes (forward/periodic/pairing.hpp): the pairing of vertices on opposite faces of a
// periodic box, checked against the definition (each vertex is its class representative
// translated by whole box edges) on generated and gmsh meshes, and the errors for meshes and
// boxes that do not fit.

#include "forward/common/error.hpp"
#include "forward/mesh/gmsh_reader.hpp"
#include "forward/periodic/pairing.hpp"

#include <gtest/gtest.h>

#include <set>
#include <string>

using namespace diffipc;

namespace {

PeriodicBox box_of(const Mesh& mesh, std::array<bool, 3> periodic = { { true, true, true } })
{
    PeriodicBox box;
    box.lower = mesh.rest_positions.colwise().minCoeff().transpose();
    box.upper = mesh.rest_positions.colwise().maxCoeff().transpose();
    box.periodic = periodic;
    return box;
}

/// Each vertex is its class representative translated by its offset (within tol), the
/// representative has offset zero, and vertices off the periodic faces are alone in their class.
void expect_consistent(const Mesh& mesh, const PeriodicBox& box, const PeriodicPairing& p, double tol)
{
    const int d = mesh.dim;
    std::vector<int> members(size_t(p.num_classes()), 0);
    for (Index v = 0; v < mesh.num_vertices(); ++v) {
        const int c = p.vertex_class[v];
        ASSERT_GE(c, 0);
        ASSERT_LT(c, p.num_classes());
        ++members[size_t(c)];
        const Index r = p.representative[c];
        for (int a = 0; a < d; ++a) {
            const double expected = mesh.rest_positions(r, a) + p.offset(v, a) * box.length(a);
            EXPECT_NEAR(mesh.rest_positions(v, a), expected, tol) << "vertex " << v << " axis " << a;
            if (!box.periodic[size_t(a)])
                EXPECT_EQ(p.offset(v, a), 0);
        }
        EXPECT_EQ(p.offset.row(r).cwiseAbs().sum(), 0) << "representative " << r << " has an offset";
    }
    for (Index v = 0; v < mesh.num_vertices(); ++v) {
        bool on_face = false;
        for (int a = 0; a < d; ++a)
            on_face = on_face
                || (box.periodic[size_t(a)]
                    && (std::abs(mesh.rest_positions(v, a) - box.lower[a]) < tol
                        || std::abs(mesh.rest_positions(v, a) - box.upper[a]) < tol));
        if (!on_face)
            EXPECT_EQ(members[size_t(p.vertex_class[v])], 1) << "interior vertex " << v << " shares a class";
    }
}

std::string message_of(const Mesh& mesh, const PeriodicBox& box)
{
    try {
        pair_periodic_vertices(mesh, box, 1e-9, "bodies[0].mesh");
    } catch (const InputError& e) {
        return e.what();
    }
    return "no error";
}

} // namespace

TEST(Periodic, BoxMeshesPairAcrossEveryPeriodicAxis)
{
    // A box of nx x ny (x nz) cells has nx ny (nz) classes when every axis is periodic; with x
    // alone, nx (ny + 1) (nz + 1). A corner's class holds 2^d vertices.
    {
        const Mesh m = box_mesh(2, VectorXd::Zero(2), (VectorXd(2) << 2, 1).finished(), (VectorXi(2) << 4, 3).finished());
        const PeriodicBox box = box_of(m);
        const PeriodicPairing p = pair_periodic_vertices(m, box, 1e-9, "mesh");
        EXPECT_EQ(p.num_classes(), 12);
        expect_consistent(m, box, p, 1e-12);
        EXPECT_EQ((p.vertex_class.array() == p.vertex_class[0]).count(), 4);
        const PeriodicBox x_only = box_of(m, { { true, false, false } });
        const PeriodicPairing px = pair_periodic_vertices(m, x_only, 1e-9, "mesh");
        EXPECT_EQ(px.num_classes(), 4 * 4);
        expect_consistent(m, x_only, px, 1e-12);
    }
    {
        const Mesh m = box_mesh(3, VectorXd::Constant(3, -0.5), VectorXd::Constant(3, 0.5), (VectorXi(3) << 3, 2, 2).finished());
        const PeriodicBox box = box_of(m);
        const PeriodicPairing p = pair_periodic_vertices(m, box, 1e-9, "mesh");
        EXPECT_EQ(p.num_classes(), 12);
        expect_consistent(m, box, p, 1e-12);
        EXPECT_EQ((p.vertex_class.array() == p.vertex_class[0]).count(), 8);
        const PeriodicBox xz = box_of(m, { { true, false, true } });
        const PeriodicPairing pxz = pair_periodic_vertices(m, xz, 1e-9, "mesh");
        EXPECT_EQ(pxz.num_classes(), 3 * 3 * 2);
        expect_consistent(m, xz, pxz, 1e-12);
    }
}

TEST(Periodic, AGmshCellWithAHolePairsItsEdges)
{
    // tests/data/periodic/square_hole.msh (make_square_hole.py): the unit square with a hole,
    // meshed by gmsh with periodic edges. Its boundary then keeps only the hole.
    Mesh m = read_gmsh(std::string(DIFFIPC_SOURCE_DIR) + "/tests/data/periodic/square_hole.msh", 2);
    const PeriodicBox box = box_of(m);
    const PeriodicPairing p = pair_periodic_vertices(m, box, 1e-9, "mesh");
    expect_consistent(m, box, p, 1e-9);
    Index on_faces = 0;
    for (Index v = 0; v < m.num_vertices(); ++v)
        on_faces += m.rest_positions(v, 0) < 1e-9 || m.rest_positions(v, 0) > 1 - 1e-9 || m.rest_positions(v, 1) < 1e-9
            || m.rest_positions(v, 1) > 1 - 1e-9;
    ASSERT_GT(on_faces, 20);
    // Each pair of opposite edges merges: the classes are the vertices less half the face vertices
    // but the corners (4 of them, one class).
    EXPECT_EQ(p.num_classes(), m.num_vertices() - (on_faces - 4) / 2 - 3);
    compute_boundary(m);
    remove_periodic_facets(m, box, 1e-9);
    ASSERT_GT(m.boundary_facets.rows(), 0);
    for (Index f = 0; f < m.boundary_facets.rows(); ++f)
        for (int i = 0; i < 2; ++i) {
            const Eigen::RowVector2d x = m.rest_positions.row(m.boundary_facets(f, i));
            EXPECT_NEAR((x - Eigen::RowVector2d(0.5, 0.5)).norm(), 0.3, 1e-9) << "facet " << f << " is not on the hole";
        }
}

TEST(Periodic, PeriodicFacesAreNoBoundary)
{
    Mesh m = box_mesh(2, VectorXd::Zero(2), VectorXd::Ones(2), (VectorXi(2) << 3, 2).finished());
    compute_boundary(m);
    ASSERT_EQ(m.boundary_facets.rows(), 10);
    Mesh x_only = m;
    remove_periodic_facets(x_only, box_of(m, { { true, false, false } }), 1e-9);
    EXPECT_EQ(x_only.boundary_facets.rows(), 6); // bottom and top
    for (Index f = 0; f < x_only.boundary_facets.rows(); ++f) {
        const double y = x_only.rest_positions(x_only.boundary_facets(f, 0), 1);
        EXPECT_TRUE(y == 0 || y == 1);
        EXPECT_EQ(x_only.rest_positions(x_only.boundary_facets(f, 1), 1), y);
    }
    remove_periodic_facets(m, box_of(m), 1e-9);
    EXPECT_EQ(m.boundary_facets.rows(), 0);
}

TEST(Periodic, MeshesAndBoxesThatDoNotFitAreErrorsNamingTheVertexOrField)
{
    Mesh m = box_mesh(2, VectorXd::Zero(2), VectorXd::Ones(2), (VectorXi(2) << 3, 3).finished());
    const PeriodicBox box = box_of(m);
    EXPECT_EQ(message_of(m, box), "no error");
    // A vertex of the right edge moved along it: no partner on the left edge.
    Mesh moved = m;
    Index right = -1;
    for (Index v = 0; v < m.num_vertices(); ++v)
        if (m.rest_positions(v, 0) == 1 && m.rest_positions(v, 1) > 0 && m.rest_positions(v, 1) < 1)
            right = v;
    ASSERT_GE(right, 0);
    moved.rest_positions(right, 1) += 0.05;
    EXPECT_EQ(message_of(moved, box).find("bodies[0].mesh: the mesh is not periodic along x: vertex "
                                          + std::to_string(right) + " at (1, "),
        0u)
        << message_of(moved, box);
    EXPECT_NE(message_of(moved, box).find("on the face x = 1 has no partner on the face x = 0"), std::string::npos);
    // A box that does not match the mesh along a periodic axis, or that cuts it along another.
    PeriodicBox wide = box;
    wide.upper[0] = 1.5;
    EXPECT_EQ(message_of(m, wide).find("periodic.box: along the periodic axis x the box spans [0, 1.5] m but the "
                                       "mesh spans [0, 1] m"),
        0u)
        << message_of(m, wide);
    PeriodicBox narrow = box_of(m, { { true, false, false } });
    narrow.upper[1] = 0.5;
    EXPECT_EQ(message_of(m, narrow).find("periodic.box: the mesh spans [0, 1] m along y, outside"), 0u)
        << message_of(m, narrow);
    PeriodicBox none = box;
    none.periodic = { { false, false, false } };
    EXPECT_EQ(message_of(m, none), "periodic.axes: no axis is periodic");
}
