// shape_opt/parametrization/boundary_extension.hpp: the harmonic extension reproduces a
// linear displacement exactly (P1 harmonic functions include the linear ones: checked on
// the positions, independently of the code), keeps unselected boundary vertices, and its
// vector-Jacobian product matches central differences.

#include "shape_opt/parametrization/boundary_extension.hpp"
#include "tests/shape_opt/parametrization/map_check.hpp"

#include "forward/common/error.hpp"

#include <gtest/gtest.h>

using namespace diffipc;

namespace {
std::vector<Index> boundary_vertices(const Mesh& mesh)
{
    std::vector<char> on(size_t(mesh.num_vertices()), 0);
    for (Index f = 0; f < mesh.boundary_facets.rows(); ++f)
        for (Index a = 0; a < mesh.boundary_facets.cols(); ++a)
            on[size_t(mesh.boundary_facets(f, a))] = 1;
    std::vector<Index> out;
    for (Index v = 0; v < mesh.num_vertices(); ++v)
        if (on[size_t(v)])
            out.push_back(v);
    return out;
}
} // namespace

TEST(BoundaryExtension, ALinearBoundaryMotionMovesTheInteriorLinearly)
{
    for (int dim : { 2, 3 }) {
        const Mesh mesh = dim == 2 ? box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(2, 1), Eigen::Vector2i(8, 5))
                                   : box_mesh(3, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 2), Eigen::Vector3i(3, 4, 5));
        const std::vector<Index> boundary = boundary_vertices(mesh);
        std::vector<int> axes(static_cast<size_t>(dim));
        for (int a = 0; a < dim; ++a)
            axes[size_t(a)] = a;
        const BoundaryExtension map(mesh, boundary, axes, "design");
        MatrixXd A = MatrixXd::Random(dim, dim) * 0.1;
        VectorXd b = VectorXd::Random(dim);
        VectorXd x(map.in_size());
        for (size_t i = 0; i < boundary.size(); ++i)
            x.segment(Index(i) * dim, dim) = A * mesh.rest_positions.row(boundary[i]).transpose() + b;
        const VectorXd y = map.apply(x);
        for (Index v = 0; v < mesh.num_vertices(); ++v) {
            const VectorXd X = mesh.rest_positions.row(v).transpose();
            EXPECT_LT((y.segment(v * dim, dim) - (X + A * X + b)).norm(), 1e-12) << "dim " << dim << " vertex " << v;
        }
        EXPECT_LT((map.inverse(y, "f") - x).norm(), 1e-12);
        test::expect_vjp_matches_differences(map, x, 1e-6, 1e-7, 3);
    }
}

TEST(BoundaryExtension, UnselectedBoundaryStaysAndInactiveAxesDoNotMove)
{
    const Mesh mesh = box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1), Eigen::Vector2i(6, 6));
    // The top edge moves up and down (axis 1 only).
    std::vector<Index> top;
    for (Index v = 0; v < mesh.num_vertices(); ++v)
        if (mesh.rest_positions(v, 1) == 1.0)
            top.push_back(v);
    const BoundaryExtension map(mesh, top, { 1 }, "design");
    ASSERT_EQ(map.in_size(), Index(top.size()));
    VectorXd x(map.in_size());
    for (Index i = 0; i < x.size(); ++i)
        x[i] = 0.05 * std::sin(3.0 * mesh.rest_positions(top[size_t(i)], 0));
    const VectorXd y = map.apply(x);
    const std::vector<Index> boundary = boundary_vertices(mesh);
    for (Index v = 0; v < mesh.num_vertices(); ++v) {
        EXPECT_EQ(y[2 * v], mesh.rest_positions(v, 0)) << v; // axis 0 is not active
        const bool on_top = mesh.rest_positions(v, 1) == 1.0;
        const bool on_boundary = std::find(boundary.begin(), boundary.end(), v) != boundary.end();
        if (on_boundary && !on_top)
            EXPECT_EQ(y[2 * v + 1], mesh.rest_positions(v, 1)) << v;
        // Maximum principle of a harmonic function: interior motion within the boundary's.
        EXPECT_LE(std::abs(y[2 * v + 1] - mesh.rest_positions(v, 1)), x.cwiseAbs().maxCoeff() + 1e-15);
    }
    test::expect_vjp_matches_differences(map, x);
}

TEST(BoundaryExtension, BadSelectionsNameTheField)
{
    const Mesh mesh = box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1), Eigen::Vector2i(4, 4));
    const Index interior = 6; // (1, 1) of the 5 x 5 grid
    EXPECT_THROW(BoundaryExtension(mesh, { interior }, { 0 }, "design.maps[0]"), InputError);
    EXPECT_THROW(BoundaryExtension(mesh, { 0, 0 }, { 0 }, "design.maps[0]"), InputError);
    EXPECT_THROW(BoundaryExtension(mesh, { 0 }, { 2 }, "design.maps[0]"), InputError);
    EXPECT_THROW(BoundaryExtension(mesh, { 99 }, { 0 }, "design.maps[0]"), InputError);
    try {
        BoundaryExtension(mesh, { interior }, { 0 }, "design.maps[0]");
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), "design.maps[0]");
    }
}
