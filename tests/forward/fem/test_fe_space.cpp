#include "forward/fem/fe_space.hpp"
#include "tests/forward/test_utils.hpp"

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <limits>

using namespace diffipc;

namespace {

Mesh cube(int dim, int n)
{
    if (dim == 2)
        return box_mesh(2, Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 0.5), Eigen::Vector2i(n, n));
    return box_mesh(3, Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0.5, 0.7), Eigen::Vector3i(n, n, n));
}

TEST(FESpace, MassesSumToTotalMass)
{
    for (int dim : { 2, 3 }) {
        const Mesh m = cube(dim, 3);
        const FESpace space(m);
        const double volume = dim == 2 ? 0.5 : 0.35;
        const VectorXd rho = VectorXd::Constant(m.num_elements(), 1200.0);
        EXPECT_NEAR(space.lumped_masses(rho).sum(), 1200.0 * volume, 1e-9);
        // Each component of the consistent mass carries the total mass once.
        EXPECT_NEAR(SparseMatrixd(space.consistent_mass(rho)).sum(), dim * 1200.0 * volume, 1e-9);
    }
}

TEST(FESpace, MinVolumeRatioIsTheSmallestElementRatio)
{
    // Against a plain loop over the elements (their signed volumes from the cross product, independent of
    // the code under test), on a large enough mesh for the parallel loop to split, with one element
    // inverted: the same value bit for bit.
    for (int dim : { 2, 3 }) {
        const Mesh m = cube(dim, dim == 2 ? 120 : 24);
        const FESpace space(m);
        VectorXd x = flatten(m.rest_positions) + 1e-3 * test::random_vector(m.num_dofs(), 5);
        const Index flipped = m.elements(m.num_elements() / 3, 0);
        x[flipped * dim] += 0.2; // moves one vertex across its neighbours: inverted elements
        const Positions P = unflatten(x, dim);
        double expected = std::numeric_limits<double>::infinity();
        for (Index e = 0; e < m.num_elements(); ++e) {
            double v;
            if (dim == 2) {
                const Eigen::Vector2d a = P.row(m.elements(e, 0)), b = P.row(m.elements(e, 1)),
                                      c = P.row(m.elements(e, 2));
                v = 0.5 * ((b - a)[0] * (c - a)[1] - (b - a)[1] * (c - a)[0]);
            } else {
                const Eigen::Vector3d a = P.row(m.elements(e, 0)), b = P.row(m.elements(e, 1)),
                                      c = P.row(m.elements(e, 2)), d = P.row(m.elements(e, 3));
                v = (b - a).cross(c - a).dot(d - a) / 6.0;
            }
            expected = std::min(expected, v / space.rest_volumes()[size_t(e)]);
        }
        EXPECT_LT(expected, 0) << "the test's deformation inverts no element";
        EXPECT_EQ(space.min_volume_ratio(x), expected) << dim << "D";
    }
}

TEST(FESpace, DeformationGradientOfAffineMapIsItsMatrix)
{
    const Mesh m = cube(3, 2);
    const FESpace space(m);
    Eigen::Matrix3d A;
    A << 1.1, 0.2, -0.1, 0.05, 0.9, 0.3, 0.0, -0.2, 1.3;
    Positions x = m.rest_positions * A.transpose();
    x.rowwise() += Eigen::RowVector3d(0.3, -1.0, 2.0);
    const VectorXd xf = flatten(x);
    for (Index e = 0; e < m.num_elements(); ++e) {
        double F[9];
        space.deformation_gradient(e, xf, F);
        EXPECT_LT((Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(F) - A).norm(), 1e-12);
    }
}

TEST(VolumePolynomial, MatchesDirectDeterminants)
{
    for (int dim : { 2, 3 }) {
        const Mesh m = cube(dim, 2);
        const VectorXd x = flatten(m.rest_positions);
        const VectorXd p = test::random_vector(x.size(), 5);
        for (Index e = 0; e < m.num_elements(); ++e) {
            const Eigen::Vector4d c = volume_polynomial(m, e, x, p);
            for (double t : { 0.0, 0.3, 1.0, 2.7 }) {
                const double direct = signed_volume(unflatten(x + t * p, dim), m.elements, e) * (dim == 2 ? 2.0 : 6.0);
                EXPECT_NEAR(((c[3] * t + c[2]) * t + c[1]) * t + c[0], direct, 1e-12 * (1 + std::abs(direct)));
            }
        }
    }
}

// The bound is checked independently: volumes are recomputed from positions
// on a fine sampling of [0, t_max] and must stay above the kept fraction.
TEST(InversionFreeStep, NoElementLosesItsVolumeAlongTheBoundedStep)
{
    for (int dim : { 2, 3 }) {
        const Mesh m = cube(dim, 3);
        const VectorXd x = flatten(m.rest_positions);
        int limited = 0;
        for (unsigned seed = 0; seed < 20; ++seed) {
            const VectorXd p = 0.5 * test::random_vector(x.size(), 300 + seed);
            const double t_max = inversion_free_step(m, x, p, 0.1);
            ASSERT_GT(t_max, 0);
            ASSERT_LE(t_max, 1);
            limited += t_max < 1;
            for (int k = 0; k <= 200; ++k) {
                const double t = t_max * k / 200.0;
                const Positions xt = unflatten(x + t * p, dim);
                for (Index e = 0; e < m.num_elements(); ++e)
                    ASSERT_GT(signed_volume(xt, m.elements, e),
                        0.1 * signed_volume(m.rest_positions, m.elements, e) * (1 - 1e-9))
                        << "dim " << dim << " seed " << seed << " element " << e << " t " << t;
            }
            // Not over-conservative: somewhat beyond t_max some element does drop below the kept fraction.
            if (t_max < 1) {
                const double t = std::min(1.0, t_max * 1.001 + 1e-12);
                const Positions xt = unflatten(x + t * p, dim);
                bool below = false;
                for (Index e = 0; e < m.num_elements(); ++e)
                    below = below
                        || signed_volume(xt, m.elements, e) < 0.1 * signed_volume(m.rest_positions, m.elements, e);
                EXPECT_TRUE(below) << "dim " << dim << " seed " << seed;
            }
        }
        EXPECT_GT(limited, 5) << "the random steps should invert elements often enough to exercise the bound";
    }
}

TEST(InversionFreeStep, FullStepWhenVolumesOnlyGrow)
{
    const Mesh m = cube(3, 2);
    const VectorXd x = flatten(m.rest_positions);
    EXPECT_EQ(inversion_free_step(m, x, 0.5 * x, 0.1), 1.0); // uniform expansion
}

} // namespace
