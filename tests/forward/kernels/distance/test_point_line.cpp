// Point-line squared distance: the value against an independent projection
// formula, derivatives against central differences, including points on the
// line, on its extension and at 1e-12 from it.

#include "fd_check.hpp"
#include "forward/contact/distance/point_line.hpp"

using namespace diffipc;
using namespace diffipc::test;

namespace {

const auto value = [](const Vec<9>& x) { return point_line_distance(vertex(x, 0), vertex(x, 1), vertex(x, 2)); };
const auto gradient
    = [](const Vec<9>& x) { return point_line_distance_gradient(vertex(x, 0), vertex(x, 1), vertex(x, 2)); };
const auto hessian
    = [](const Vec<9>& x) { return point_line_distance_hessian(vertex(x, 0), vertex(x, 1), vertex(x, 2)); };

/// |r - (r.u) u|^2 with u the unit direction: the projection form, not the
/// cross-product form the implementation uses.
double projection_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1)
{
    const Eigen::Vector3d u = (e1 - e0).normalized();
    const Eigen::Vector3d r = p - e0;
    return (r - r.dot(u) * u).squaredNorm();
}

} // namespace

TEST(PointLineDistance, DerivativesMatchFiniteDifferencesOnRandomConfigurations)
{
    RandomPoints random(21);
    for (int k = 0; k < 50; ++k) {
        Eigen::Vector3d p = random(), e0 = random(), e1 = random();
        if ((e1 - e0).norm() < 0.2) // keep the conditioning of the generic case
            continue;
        const Vec<9> x = stack(p, e0, e1);
        EXPECT_NEAR(value(x), projection_distance(p, e0, e1), 1e-14);
        expect_derivatives<9>(value, gradient, hessian, x, {}, "config " + std::to_string(k));
    }
}

TEST(PointLineDistance, PointOnTheLineAndItsExtension)
{
    // d = 0 there and the gradient is exactly zero; the Hessian is the
    // projector 2 (I - u u^T)-like matrix. Since d is smooth in p across the
    // line, central differences still converge at O(h^2) up to round-off. The
    // floor 1 makes errors absolute against an O(1) Hessian.
    const Eigen::Vector3d e0(0.1, -0.3, 0.2), e1(0.9, 0.4, -0.5);
    for (double t : { 0.0, 0.25, 1.0, 1.5, -2.0 }) {
        const Eigen::Vector3d p = e0 + t * (e1 - e0);
        const Vec<9> x = stack(p, e0, e1);
        EXPECT_LE(value(x), 1e-30);
        FdOptions opt;
        opt.floor = 1;
        expect_derivatives<9>(value, gradient, hessian, x, opt, "t = " + std::to_string(t));
    }
}

TEST(PointLineDistance, PointWithinTinyOffsetsOfTheLine)
{
    // The separation 1e-12 is resolved only to ~1e-16 by O(1) coordinates,
    // so the value and the gradient (both carry the separation as a factor)
    // are known to ~1e-4 relative at best; the Hessian is O(1) and keeps
    // full accuracy. Tolerances: 1e-3 on the gradient, 1e-7 on the Hessian.
    // The third derivatives are O(1), so the gradient's truncation error
    // h^2 must stay below 1e-12 * tolerance: steps go down to 1e-10.
    RandomPoints random(22);
    for (int k = 0; k < 10; ++k) {
        const Eigen::Vector3d e0 = random(), e1 = random();
        Eigen::Vector3d n = random.direction();
        n = (n - n.dot((e1 - e0).normalized()) * (e1 - e0).normalized()).normalized();
        const Eigen::Vector3d p = e0 + random.uniform(-0.5, 1.5) * (e1 - e0) + 1e-12 * n;
        const Vec<9> x = stack(p, e0, e1);
        EXPECT_NEAR(std::sqrt(value(x)), 1e-12, 1e-15);
        FdOptions opt;
        opt.gradient_tolerance = 1e-3;
        opt.check_order = false;
        opt.step_scale = 1e-3;
        expect_derivatives<9>(value, gradient, hessian, x, opt, "config " + std::to_string(k));
    }
}
