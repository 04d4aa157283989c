// shape_opt/parametrization/smoothing_filter.hpp against a brute-force evaluation of its
// formula, and its vector-Jacobian product against central differences.

#include "shape_opt/parametrization/smoothing_filter.hpp"
#include "tests/shape_opt/parametrization/map_check.hpp"

#include "forward/common/error.hpp"

#include <gtest/gtest.h>

#include <random>

using namespace diffipc;

namespace {
struct Cloud {
    MatrixXd centroids;
    VectorXd volumes;
};

Cloud random_cloud(Index n, int dim, unsigned seed)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    Cloud c { MatrixXd(n, dim), VectorXd(n) };
    for (Index e = 0; e < n; ++e) {
        for (int a = 0; a < dim; ++a)
            c.centroids(e, a) = 2.0 * u(rng) - 0.5;
        c.volumes[e] = 0.5 + u(rng);
    }
    return c;
}
} // namespace

TEST(SmoothingFilter, MatchesTheFormulaEvaluatedPairByPair)
{
    for (int dim : { 1, 2, 3 }) {
        const Cloud c = random_cloud(300, dim, 7 + dim);
        const double r = 0.3;
        const SmoothingFilter filter(c.centroids, c.volumes, r, "filter");
        VectorXd x(300);
        std::mt19937 rng(3);
        std::normal_distribution<double> g;
        for (Index e = 0; e < 300; ++e)
            x[e] = g(rng);
        const VectorXd y = filter.apply(x);
        for (Index e = 0; e < 300; ++e) {
            double num = 0, den = 0;
            for (Index f = 0; f < 300; ++f) {
                const double w = c.volumes[f] * std::max(0.0, r - (c.centroids.row(e) - c.centroids.row(f)).norm());
                num += w * x[f];
                den += w;
            }
            EXPECT_NEAR(y[e], num / den, 1e-12) << "dim " << dim << " element " << e;
        }
        test::expect_vjp_matches_differences(filter, x);
    }
}

TEST(SmoothingFilter, KeepsConstantsAndIsTheIdentityBelowTheSpacing)
{
    const Cloud c = random_cloud(50, 2, 1);
    const SmoothingFilter wide(c.centroids, c.volumes, 0.5, "filter");
    const VectorXd ones = VectorXd::Constant(50, 3.5);
    EXPECT_LT((wide.apply(ones) - ones).lpNorm<Eigen::Infinity>(), 1e-13);
    // A grid of spacing 1: a radius of 0.9 reaches no neighbour.
    MatrixXd grid(16, 2);
    for (int i = 0; i < 16; ++i)
        grid.row(i) << i % 4, i / 4;
    const SmoothingFilter narrow(grid, VectorXd::Ones(16), 0.9, "filter");
    const VectorXd x = VectorXd::LinSpaced(16, -1, 2);
    EXPECT_EQ(narrow.apply(x), x);
    EXPECT_THROW(SmoothingFilter(grid, VectorXd::Ones(16), 0.0, "design.maps[1].radius"), InputError);
    EXPECT_THROW(SmoothingFilter(grid, VectorXd::Ones(16), std::nan(""), "design.maps[1].radius"), InputError);
}
