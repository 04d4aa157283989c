// Line-line squared distance: the value against closest points from the
// normal equations, derivatives against central differences on random
// configurations, for nearly parallel lines (angles 1e-3 .. 1e-6) and for
// lines 1e-12 apart.

#include "fd_check.hpp"
#include "forward/contact/distance/line_line.hpp"

#include <Eigen/Dense>

using namespace diffipc;
using namespace diffipc::test;

namespace {

const auto value
    = [](const Vec<12>& x) { return line_line_distance(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3)); };
const auto gradient = [](const Vec<12>& x) {
    return line_line_distance_gradient(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3));
};
const auto hessian = [](const Vec<12>& x) {
    return line_line_distance_hessian(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3));
};

/// Closest points of the two lines from the 2x2 normal equations.
double normal_equations_distance(
    const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0, const Eigen::Vector3d& eb1)
{
    Eigen::Matrix<double, 3, 2> A;
    A << ea1 - ea0, -(eb1 - eb0);
    const Eigen::Vector2d st = (A.transpose() * A).ldlt().solve(A.transpose() * (eb0 - ea0));
    return (ea0 + st[0] * (ea1 - ea0) - eb0 - st[1] * (eb1 - eb0)).squaredNorm();
}

/// Line a through (-1, 0, 0) and (1, 0, 0); line b through two points 2
/// apart in the plane z = gap, at `angle` to a, whose projection crosses a
/// at (shift, 0) midway between them; then a random rigid motion.
Vec<12> crossing_lines(double angle, double gap, RandomPoints& random, double shift = 0)
{
    const Eigen::Vector3d ea0(-1, 0, 0), ea1(1, 0, 0);
    const Eigen::Vector3d d(std::cos(angle), std::sin(angle), 0), c(shift, 0, gap);
    const Eigen::Matrix3d R = random.rotation();
    const Eigen::Vector3d t = random();
    return stack(Eigen::Vector3d(R * ea0 + t), Eigen::Vector3d(R * ea1 + t), Eigen::Vector3d(R * (c - d) + t),
        Eigen::Vector3d(R * (c + d) + t));
}

} // namespace

TEST(LineLineDistance, DerivativesMatchFiniteDifferencesOnRandomConfigurations)
{
    RandomPoints random(41);
    int tested = 0;
    while (tested < 50) {
        const Eigen::Vector3d ea0 = random(), ea1 = random(), eb0 = random(), eb1 = random();
        const Eigen::Vector3d a = ea1 - ea0, b = eb1 - eb0;
        // Angles above ~15 degrees and edges of reasonable length: the
        // generic case. Near-parallel lines have their own test.
        if (a.norm() < 0.3 || b.norm() < 0.3 || a.cross(b).norm() < 0.25 * a.norm() * b.norm())
            continue;
        const Vec<12> x = stack(ea0, ea1, eb0, eb1);
        EXPECT_NEAR(value(x), normal_equations_distance(ea0, ea1, eb0, eb1), 1e-13);
        expect_derivatives<12>(value, gradient, hessian, x, {}, "config " + std::to_string(tested++));
    }
}

TEST(LineLineDistance, NearlyParallelLines)
{
    // Value: rounding the rotated positions to ~1e-16 moves the distance by
    // ~1e-16 (|grad sqrt(d)| = 1), i.e. d by ~2e-16 gap; 4e-15 gap leaves a
    // margin of 10. A formula that dots the full ea0 - eb0 with the cross
    // product of the edges loses eps |ea0 - eb0| / (angle gap) relatively
    // (1e-11 absolute at angle 1e-6, shift 0.9) and fails this.
    //
    // Derivatives: they vary over lengths ~angle (tilting an edge by delta
    // moves the closest points by ~gap delta / angle^2), so steps scale with
    // the angle. Two limits on the agreement: (1) the gradient itself is
    // only determined by double inputs to ~1e-16 gap / angle^2 relative
    // (its condition number; 5e-6 at angle 1e-6, gap 0.1, measured against
    // quad precision), (2) central differences balance a truncation error
    // C (h / angle)^2 against round-off ~1e-16 / h. The worst best-step
    // errors measured over rotations, shifts and gaps are ~1e-11 / angle;
    // the tolerance is 1e-10 / angle. The observed order 2 over the
    // truncation-dominated steps is the stronger check: a wrong derivative
    // would plateau instead.
    RandomPoints random(42);
    for (double angle : { 1e-3, 1e-4, 1e-5, 1e-6 }) {
        for (double shift : { 0.0, 0.3, 0.9 }) {
            for (double gap : { 0.1, 1e-3 }) {
                const std::string what = "angle " + std::to_string(angle) + ", shift " + std::to_string(shift)
                    + ", gap " + std::to_string(gap);
                const Vec<12> x = crossing_lines(angle, gap, random, shift);
                EXPECT_NEAR(value(x), gap * gap, 4e-15 * gap) << what;
                FdOptions opt;
                opt.gradient_tolerance = opt.hessian_tolerance = 1e-10 / angle;
                opt.step_scale = angle;
                expect_derivatives<12>(value, gradient, hessian, x, opt, what);
                EXPECT_GT(hessian(x).cwiseAbs().maxCoeff(), 0.1 * gap * gap / (angle * angle))
                    << "the 1/angle^2 growth the mollifier tames";
            }
        }
    }
}

TEST(LineLineDistance, LinesWithinTinyOffsets)
{
    // Crossing lines 1e-12 apart: as for point-plane, the gradient carries
    // the 1e-12 gap, resolved to ~1e-4 relative by O(1) coordinates (1e-3),
    // the O(1) Hessian keeps 1e-7; O(1) third derivatives need steps to 1e-10.
    RandomPoints random(43);
    for (double angle : { 1.0, 0.3 }) {
        const Vec<12> x = crossing_lines(angle, 1e-12, random);
        EXPECT_NEAR(std::sqrt(value(x)), 1e-12, 1e-15);
        FdOptions opt;
        opt.gradient_tolerance = 1e-3;
        opt.check_order = false;
        opt.step_scale = 1e-3;
        expect_derivatives<12>(value, gradient, hessian, x, opt, "angle " + std::to_string(angle));
    }
}
