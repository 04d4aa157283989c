// Point-plane squared distance: the value against an independent formula,
// derivatives against central differences on random configurations, for
// points in the plane, 1e-12 off it, and exactly above a corner or an edge.

#include "fd_check.hpp"
#include "forward/contact/distance/point_plane.hpp"

#include <Eigen/Geometry>

using namespace diffipc;
using namespace diffipc::test;

namespace {

const auto value
    = [](const Vec<12>& x) { return point_plane_distance(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3)); };
const auto gradient = [](const Vec<12>& x) {
    return point_plane_distance_gradient(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3));
};
const auto hessian = [](const Vec<12>& x) {
    return point_plane_distance_hessian(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3));
};

/// Unit normal built from a different corner than the implementation's.
double independent_distance(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2)
{
    const Eigen::Vector3d n = (t2 - t1).cross(t0 - t1).normalized();
    const double h = (p - t1).dot(n);
    return h * h;
}

/// Triangle angles above ~15 degrees, so that random cases are well conditioned.
bool well_shaped(const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2)
{
    const Eigen::Vector3d a = t1 - t0, b = t2 - t0, c = t2 - t1;
    const double area2 = a.cross(b).norm();
    const double longest = std::max({ a.norm(), b.norm(), c.norm() });
    return area2 > 0.25 * longest * longest && longest > 0.3;
}

} // namespace

TEST(PointPlaneDistance, DerivativesMatchFiniteDifferencesOnRandomConfigurations)
{
    RandomPoints random(31);
    int tested = 0;
    while (tested < 50) {
        const Eigen::Vector3d p = random(), t0 = random(), t1 = random(), t2 = random();
        if (!well_shaped(t0, t1, t2))
            continue;
        const Vec<12> x = stack(p, t0, t1, t2);
        EXPECT_NEAR(value(x), independent_distance(p, t0, t1, t2), 1e-14);
        expect_derivatives<12>(value, gradient, hessian, x, {}, "config " + std::to_string(tested++));
    }
}

TEST(PointPlaneDistance, PointInThePlaneAndAboveCornersAndEdges)
{
    // In the plane the distance and its gradient vanish (floor 1: errors
    // absolute against the O(1) Hessian). Above a corner or an edge
    // (where the point-triangle type switches) the formula is as smooth as
    // anywhere, so the generic tolerance and order apply.
    const Eigen::Vector3d t0(0.1, 0.2, -0.1), t1(1.0, 0.3, 0.2), t2(0.3, 1.1, 0.4);
    const Eigen::Vector3d n = (t1 - t0).cross(t2 - t0).normalized();
    const Eigen::Vector3d feet[] = { t0, t1, t2, (t0 + t1) / 2, 0.3 * t1 + 0.7 * t2, (t0 + t1 + t2) / 3 };
    for (const Eigen::Vector3d& foot : feet) {
        for (double height : { 0.0, 0.05, -0.3 }) {
            const Vec<12> x = stack(Eigen::Vector3d(foot + height * n), t0, t1, t2);
            EXPECT_NEAR(value(x), height * height, 1e-15);
            FdOptions opt;
            opt.floor = 1;
            expect_derivatives<12>(value, gradient, hessian, x, opt, "height " + std::to_string(height));
        }
    }
}

TEST(PointPlaneDistance, PointWithinTinyOffsetsOfThePlane)
{
    // As for point-line: a 1e-12 height is resolved to ~1e-4 relative by O(1)
    // coordinates, so the gradient (proportional to the height) gets 1e-3,
    // the O(1) Hessian keeps 1e-7. Third derivatives are O(1): steps reach 1e-10.
    RandomPoints random(32);
    int tested = 0;
    while (tested < 10) {
        const Eigen::Vector3d t0 = random(), t1 = random(), t2 = random();
        if (!well_shaped(t0, t1, t2))
            continue;
        const Eigen::Vector3d n = (t1 - t0).cross(t2 - t0).normalized();
        const double u = random.uniform(-0.5, 1), v = random.uniform(-0.5, 1);
        const Eigen::Vector3d p = t0 + u * (t1 - t0) + v * (t2 - t0) + 1e-12 * n;
        const Vec<12> x = stack(p, t0, t1, t2);
        EXPECT_NEAR(std::sqrt(value(x)), 1e-12, 1e-15);
        FdOptions opt;
        opt.gradient_tolerance = 1e-3;
        opt.check_order = false;
        opt.step_scale = 1e-3;
        expect_derivatives<12>(value, gradient, hessian, x, opt, "config " + std::to_string(tested++));
    }
}
