// shape_opt/rest_validity.hpp: design steps bounded before an element inverts or the rest
// boundary intersects. The checks are independent of the code under test: element areas from
// their own cross products, and boundary crossings by brute force over every pair of
// boundary edges with orientation tests (the test geometries keep clear of ties).

#include "shape_opt/rest_validity.hpp"

#include <gtest/gtest.h>

using namespace diffipc;

namespace {

double min_area(const Mesh& m, const VectorXd& X)
{
    double smallest = std::numeric_limits<double>::infinity();
    for (Index e = 0; e < m.num_elements(); ++e) {
        const Eigen::Vector2d a = X.segment<2>(2 * m.elements(e, 0)), b = X.segment<2>(2 * m.elements(e, 1)),
                              c = X.segment<2>(2 * m.elements(e, 2));
        const Eigen::Vector2d u = b - a, v = c - a;
        smallest = std::min(smallest, 0.5 * (u[0] * v[1] - u[1] * v[0]));
    }
    return smallest;
}

double orient(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c)
{
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

bool boundary_crosses(const Mesh& m, const VectorXd& X)
{
    for (Index i = 0; i < m.boundary_facets.rows(); ++i)
        for (Index j = i + 1; j < m.boundary_facets.rows(); ++j) {
            const Index a = m.boundary_facets(i, 0), b = m.boundary_facets(i, 1), c = m.boundary_facets(j, 0),
                        d = m.boundary_facets(j, 1);
            if (a == c || a == d || b == c || b == d)
                continue;
            const Eigen::Vector2d A = X.segment<2>(2 * a), B = X.segment<2>(2 * b), C = X.segment<2>(2 * c),
                                  D = X.segment<2>(2 * d);
            const double o1 = orient(A, B, C), o2 = orient(A, B, D), o3 = orient(C, D, A), o4 = orient(C, D, B);
            if (o1 == 0 && o2 == 0) {
                // Collinear: do the projections on the line overlap?
                const Eigen::Vector2d u = B - A;
                const double c = (C - A).dot(u), d = (D - A).dot(u);
                if (std::max(c, d) >= 0 && std::min(c, d) <= u.squaredNorm())
                    return true;
            } else if (o1 * o2 <= 0 && o3 * o4 <= 0)
                return true;
        }
    return false;
}

/// Two unit squares side by side, 0.5 apart, as two bodies.
Mesh two_squares()
{
    Mesh a = box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1), Eigen::Vector2i(2, 2));
    const Mesh b = box_mesh(2, Eigen::Vector2d(1.5, 0), Eigen::Vector2d(2.5, 1), Eigen::Vector2i(2, 2));
    const Index nv = a.num_vertices(), ne = a.num_elements(), nf = a.boundary_facets.rows();
    Mesh m = a;
    m.rest_positions.resize(nv + b.num_vertices(), 2);
    m.rest_positions << a.rest_positions, b.rest_positions;
    m.elements.resize(ne + b.num_elements(), 3);
    m.elements << a.elements, (b.elements.array() + int(nv)).matrix();
    m.boundary_facets.resize(nf + b.boundary_facets.rows(), 2);
    m.boundary_facets << a.boundary_facets, (b.boundary_facets.array() + int(nv)).matrix();
    m.vertex_body = VectorXi::Zero(m.num_vertices());
    m.vertex_body.tail(b.num_vertices()).setOnes();
    m.element_body = VectorXi::Zero(m.num_elements());
    m.element_body.tail(b.num_elements()).setOnes();
    m.facet_body = VectorXi::Zero(m.boundary_facets.rows());
    m.facet_body.tail(b.boundary_facets.rows()).setOnes();
    return m;
}

} // namespace

TEST(RestValidity, AStepThatInvertsAnElementIsCutBeforeIt)
{
    const Mesh m = box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1), Eigen::Vector2i(4, 4));
    const RestValidity validity(m);
    const VectorXd X = flatten(m.rest_positions);
    EXPECT_EQ(validity.problem(X), "");
    // The centre vertex (2, 2) of the 5 x 5 grid pushed 0.6 to the right: past its neighbours at 0.25.
    VectorXd dX = VectorXd::Zero(X.size());
    dX[2 * 12] = 0.6;
    ASSERT_LT(min_area(m, X + dX), 0);
    EXPECT_NE(validity.problem(X + dX), "");
    const double t = validity.max_step(X, dX);
    ASSERT_GT(t, 0);
    ASSERT_LT(t, 1);
    for (int k = 0; k <= 100; ++k)
        EXPECT_GT(min_area(m, X + (t * k / 100.0) * dX), 0) << k;
    EXPECT_EQ(validity.problem(X + t * dX), "");
}

TEST(RestValidity, AStepThatMovesABodyIntoAnotherIsCutBeforeContact)
{
    const Mesh m = two_squares();
    const RestValidity validity(m);
    const VectorXd X = flatten(m.rest_positions);
    EXPECT_EQ(validity.problem(X), "");
    // The left square's right column moves 1 to the right: 0.5 into the right square.
    VectorXd dX = VectorXd::Zero(X.size());
    for (Index v = 0; v < 9; ++v)
        if (m.rest_positions(v, 0) == 1.0)
            dX[2 * v] = 1.0;
    ASSERT_TRUE(boundary_crosses(m, X + dX));
    EXPECT_NE(validity.problem(X + dX), "");
    const double t = validity.max_step(X, dX);
    ASSERT_GT(t, 0.1);
    ASSERT_LT(t, 0.5); // contact at t = 0.5
    for (int k = 0; k <= 100; ++k)
        EXPECT_FALSE(boundary_crosses(m, X + (t * k / 100.0) * dX)) << k;
    EXPECT_EQ(validity.problem(X + t * dX), "");
    // A step that stays clear is not cut.
    EXPECT_EQ(validity.max_step(X, 0.2 * dX), 1.0);
}
