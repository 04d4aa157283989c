// shape_opt/parametrization/free_form_deformation.hpp: Bernstein lattices reproduce affine
// motions exactly (sum_i B_i^n(s) i / n = s, checked on positions independently), leave
// vertices outside the box in place, keep the box's faces with a fixed border, move a point
// the same way on two different meshes (the parameters do not depend on the mesh), and the
// vector-Jacobian product matches central differences.

#include "shape_opt/parametrization/basic_maps.hpp"
#include "shape_opt/parametrization/free_form_deformation.hpp"
#include "tests/shape_opt/parametrization/map_check.hpp"

#include "forward/common/error.hpp"

#include <gtest/gtest.h>

using namespace diffipc;

namespace {
FfdLattice lattice(int dim, bool fixed_border = false)
{
    FfdLattice l;
    l.lower = VectorXd::Constant(dim, 0.1);
    l.upper = VectorXd::Constant(dim, 0.8);
    l.degree = VectorXi::LinSpaced(dim, 2, 1 + dim);
    for (int a = 0; a < dim; ++a)
        l.axes.push_back(a);
    l.fixed_border = fixed_border;
    return l;
}

Mesh unit_box(int dim, int cells)
{
    return box_mesh(dim, VectorXd::Zero(dim), VectorXd::Ones(dim), VectorXi::Constant(dim, cells));
}
} // namespace

TEST(FreeFormDeformation, AnAffineLatticeMotionIsAnAffineMotionInsideTheBox)
{
    for (int dim : { 2, 3 }) {
        const Mesh mesh = unit_box(dim, 6);
        const FfdLattice l = lattice(dim);
        const FreeFormDeformation ffd(mesh.rest_positions, l, "design");
        const MatrixXd A = MatrixXd::Random(dim, dim) * 0.05;
        const VectorXd b = VectorXd::Random(dim) * 0.01;
        VectorXd x(ffd.in_size());
        for (Index c = 0; c < ffd.variable_points(); ++c)
            x.segment(c * dim, dim) = A * ffd.control_point(c) + b;
        const VectorXd y = ffd.apply(x);
        for (Index v = 0; v < mesh.num_vertices(); ++v) {
            const VectorXd X = mesh.rest_positions.row(v).transpose();
            const bool inside = (X.array() >= l.lower.array()).all() && (X.array() <= l.upper.array()).all();
            const VectorXd expected = inside ? VectorXd(X + A * X + b) : X;
            EXPECT_LT((y.segment(v * dim, dim) - expected).norm(), 1e-13) << "dim " << dim << " vertex " << v;
        }
        test::expect_vjp_matches_differences(ffd, x);
    }
}

TEST(FreeFormDeformation, TheParametersDoNotDependOnTheMesh)
{
    // (0.5, 0.5) is a vertex of both a 4 x 4 and a 10 x 10 grid of the unit square.
    const Mesh coarse = unit_box(2, 4), fine = unit_box(2, 10);
    const FfdLattice l = lattice(2);
    const FreeFormDeformation a(coarse.rest_positions, l, "design"), b(fine.rest_positions, l, "design");
    ASSERT_EQ(a.in_size(), b.in_size());
    const VectorXd x = VectorXd::Random(a.in_size()) * 0.02;
    auto moved = [&](const Mesh& m, const VectorXd& y) {
        for (Index v = 0; v < m.num_vertices(); ++v)
            if ((m.rest_positions.row(v) - Eigen::RowVector2d(0.5, 0.5)).norm() < 1e-12)
                return Eigen::Vector2d(y.segment(2 * v, 2));
        ADD_FAILURE() << "no vertex at (0.5, 0.5)";
        return Eigen::Vector2d(0, 0);
    };
    EXPECT_LT((moved(coarse, a.apply(x)) - moved(fine, b.apply(x))).norm(), 1e-14);
}

TEST(FreeFormDeformation, AFixedBorderKeepsTheBoxFaces)
{
    const Mesh mesh = unit_box(2, 10);
    FfdLattice l = lattice(2, true);
    l.lower = VectorXd::Constant(2, 0.2); // vertices at 0.2 and 0.8 lie on the faces
    const FreeFormDeformation ffd(mesh.rest_positions, l, "design");
    EXPECT_EQ(ffd.variable_points(), (2 - 1) * (3 - 1)); // degrees 2 and 3: interior 1 x 2
    const VectorXd y = ffd.apply(VectorXd::Constant(ffd.in_size(), 0.05));
    int on_faces = 0;
    for (Index v = 0; v < mesh.num_vertices(); ++v) {
        const Eigen::RowVector2d X = mesh.rest_positions.row(v);
        const bool on_face = (std::abs(X[0] - 0.2) < 1e-12 || std::abs(X[0] - 0.8) < 1e-12
                                 || std::abs(X[1] - 0.2) < 1e-12 || std::abs(X[1] - 0.8) < 1e-12)
            && X.minCoeff() >= 0.2 - 1e-12 && X.maxCoeff() <= 0.8 + 1e-12;
        if (on_face) {
            ++on_faces;
            EXPECT_LT((y.segment(2 * v, 2) - X.transpose()).norm(), 1e-15) << v;
        }
    }
    EXPECT_GT(on_faces, 10);
}

TEST(FreeFormDeformation, BadLatticesNameTheField)
{
    const Mesh mesh = unit_box(2, 2);
    FfdLattice l = lattice(2);
    l.upper[1] = l.lower[1];
    EXPECT_THROW(FreeFormDeformation(mesh.rest_positions, l, "design.maps[0]"), InputError);
    l = lattice(2);
    l.degree[0] = 0;
    EXPECT_THROW(FreeFormDeformation(mesh.rest_positions, l, "design.maps[0]"), InputError);
    l = lattice(2);
    l.axes = { 0, 0 };
    EXPECT_THROW(FreeFormDeformation(mesh.rest_positions, l, "design.maps[0]"), InputError);
    l = lattice(2, true);
    l.degree = Eigen::Vector2i(1, 3);
    EXPECT_THROW(FreeFormDeformation(mesh.rest_positions, l, "design.maps[0]"), InputError);
}

TEST(FreeFormDeformation, BorderFixedAlongSomeAxesOnly)
{
    // Faces normal to x stay; the faces normal to y move with their control points.
    const Mesh mesh = unit_box(2, 10);
    FfdLattice l = lattice(2);
    l.fixed_border_axes = { 0 };
    const FreeFormDeformation ffd(mesh.rest_positions, l, "design");
    EXPECT_EQ(ffd.variable_points(), (l.degree[0] - 1) * (l.degree[1] + 1));
    const VectorXd x = VectorXd::Random(ffd.in_size()) * 0.05;
    const VectorXd y = ffd.apply(x);
    bool y_face_moved = false;
    for (Index v = 0; v < mesh.num_vertices(); ++v) {
        const VectorXd X = mesh.rest_positions.row(v).transpose();
        const double move = (y.segment(v * 2, 2) - X).norm();
        const bool inside_y = X[1] >= l.lower[1] && X[1] <= l.upper[1];
        if (inside_y && (std::abs(X[0] - l.lower[0]) < 1e-12 || std::abs(X[0] - l.upper[0]) < 1e-12))
            EXPECT_LT(move, 1e-15) << "vertex " << v << " on a fixed face";
        if (std::abs(X[1] - l.lower[1]) < 1e-12 && X[0] > l.lower[0] + 1e-9 && X[0] < l.upper[0] - 1e-9)
            y_face_moved = y_face_moved || move > 1e-4;
    }
    EXPECT_TRUE(y_face_moved);
    test::expect_vjp_matches_differences(ffd, x);
    l.fixed_border_axes = { 2 };
    EXPECT_THROW(FreeFormDeformation(mesh.rest_positions, l, "design"), InputError);
}

// Remeshing asks a map whether it follows a new mesh (ParameterMap::remeshable_shape,
// input_survives_remesh): a free-form deformation does, through its pull-back, and its pull-back
// is the inverse of its motion; plain maps do not.
TEST(FreeFormDeformation, IsTheRemeshableShapeAndItsPullBackInvertsIt)
{
    const Mesh mesh = unit_box(2, 4);
    const FreeFormDeformation ffd(mesh.rest_positions, lattice(2), "ffd");
    const ParameterMap& map = ffd;
    ASSERT_EQ(map.remeshable_shape(), &ffd);
    EXPECT_TRUE(map.input_survives_remesh());
    EXPECT_EQ(map.remeshable_shape()->mesh_input_key(), "mesh_at");
    const VectorXd x = 0.02 * VectorXd::LinSpaced(ffd.in_size(), -1, 1);
    const VectorXd moved = ffd.apply(x);
    const Positions current = Eigen::Map<const Positions>(moved.data(), mesh.rest_positions.rows(), 2);
    const Positions back = map.remeshable_shape()->pull_back(current, x);
    EXPECT_LT((back - mesh.rest_positions).cwiseAbs().maxCoeff(), 1e-10);
    const ExpMap exp(3);
    EXPECT_EQ(exp.remeshable_shape(), nullptr);
    EXPECT_FALSE(exp.input_survives_remesh());
    const GatherMap per_element(2, { 0, 1, 1 }, "gather"), per_body(2, { 0, 1, 1 }, "per_body", "per_body", true);
    EXPECT_FALSE(per_element.input_survives_remesh());
    EXPECT_TRUE(per_body.input_survives_remesh());
}
