// Point-point squared distance: derivatives against central differences.

#include "fd_check.hpp"
#include "forward/contact/distance/point_point.hpp"

using namespace diffipc;
using namespace diffipc::test;

namespace {

const auto value = [](const Vec<6>& x) { return point_point_distance(vertex(x, 0), vertex(x, 1)); };
const auto gradient = [](const Vec<6>& x) { return point_point_distance_gradient(vertex(x, 0), vertex(x, 1)); };
const auto hessian = [](const Vec<6>& x) { return point_point_distance_hessian(vertex(x, 0), vertex(x, 1)); };

} // namespace

TEST(PointPointDistance, DerivativesMatchFiniteDifferencesOnRandomPairs)
{
    RandomPoints random(11);
    for (int k = 0; k < 50; ++k) {
        const Vec<6> x = stack(random(), random());
        EXPECT_NEAR(value(x), (vertex(x, 0) - vertex(x, 1)).squaredNorm(), 1e-15);
        expect_derivatives<6>(value, gradient, hessian, x, {}, "pair " + std::to_string(k));
    }
}

TEST(PointPointDistance, NearlyCoincidentPoints)
{
    // At a 1e-12 offset the function is still the exact quadratic, so central
    // differences are exact up to the rounding of the O(1) coordinates
    // (~1e-16 absolute, i.e. 1e-4 of the 1e-12-sized gradient): 1e-3 leaves
    // a factor 10 for that and nothing for a wrong formula.
    RandomPoints random(12);
    for (int k = 0; k < 10; ++k) {
        const Eigen::Vector3d p = random();
        const Vec<6> x = stack(p, Eigen::Vector3d(p + 1e-12 * random.direction()));
        FdOptions opt;
        opt.gradient_tolerance = 1e-3;
        opt.check_order = false;
        expect_derivatives<6>(value, gradient, hessian, x, opt, "offset 1e-12, pair " + std::to_string(k));
    }
    const Eigen::Vector3d p(0.3, -0.2, 0.7);
    EXPECT_EQ(point_point_distance_gradient(p, p), Vec<6>::Zero());
}
