// Edge-edge mollifier (IPC, Li et al. 2020): the cross product's squared
// norm and its derivatives, the threshold and its rest-position gradient,
// the scalar mollifier and its derivatives in x and eps_x, the position
// gradient and Hessian, the derivatives with respect to eps_x, the shape
// derivative obtained by chaining them, and continuity at x = eps_x.

#include "fd_check.hpp"
#include "forward/contact/distance/edge_edge_mollifier.hpp"

#include <Eigen/Geometry>

using namespace diffipc;
using namespace diffipc::test;

namespace {

Vec<12> cross_gradient(const Vec<12>& x)
{
    return edge_edge_cross_squarednorm_gradient(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3));
}

/// Central difference of a scalar function of one variable, best of several steps relative to `exact`.
template <class F> double best_relative_error_1d(const F& f, double x, double exact, double scale)
{
    double best = std::numeric_limits<double>::infinity();
    for (double h : fd_steps(scale))
        best = std::min(best, std::abs((f(x + h) - f(x - h)) / (2 * h) - exact) / std::max(std::abs(exact), 1e-300));
    return best;
}

/// Edge a of length la along x at the origin, edge b of length lb at
/// `angle` to it, 0.1 above; then a random rigid motion.
Vec<12> edge_pair(double angle, double la, double lb, RandomPoints& random)
{
    const Eigen::Matrix3d R = random.rotation();
    const Eigen::Vector3d t = random();
    const Eigen::Vector3d d = lb * Eigen::Vector3d(std::cos(angle), std::sin(angle), 0);
    const Eigen::Vector3d c(0.2, 0.1, 0.1);
    return stack(Eigen::Vector3d(t), Eigen::Vector3d(R * Eigen::Vector3d(la, 0, 0) + t),
        Eigen::Vector3d(R * (c - d / 2) + t), Eigen::Vector3d(R * (c + d / 2) + t));
}

double threshold_of(const Vec<12>& rest)
{
    return edge_edge_mollifier_threshold(vertex(rest, 0), vertex(rest, 1), vertex(rest, 2), vertex(rest, 3));
}

} // namespace

TEST(EdgeEdgeMollifier, CrossSquaredNormDerivatives)
{
    // x = |a x b|^2 is a quartic polynomial: central differences of its
    // gradient have truncation O(h^2) and no conditioning issue, so the
    // generic tolerance applies everywhere, parallel edges included (there
    // x = 0 and its gradient vanishes: floor 1 makes errors absolute against
    // the O(1) Hessian).
    const auto value = [](const Vec<12>& x) {
        return edge_edge_cross_squarednorm(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3));
    };
    const auto hessian = [](const Vec<12>& x) {
        return edge_edge_cross_squarednorm_hessian(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3));
    };
    RandomPoints random(81);
    for (int k = 0; k < 20; ++k) {
        const Vec<12> x = stack(random(), random(), random(), random());
        const Eigen::Vector3d a = vertex(x, 1) - vertex(x, 0), b = vertex(x, 3) - vertex(x, 2);
        EXPECT_NEAR(value(x), a.squaredNorm() * b.squaredNorm() - std::pow(a.dot(b), 2), 1e-14);
        expect_derivatives<12>(value, cross_gradient, hessian, x, {}, "random " + std::to_string(k));
    }
    for (double angle : { 0.0, 1e-6, 1e-3, 0.01 }) {
        const Vec<12> x = edge_pair(angle, 1.0, 0.7, random);
        FdOptions opt;
        opt.floor = 1;
        expect_derivatives<12>(value, cross_gradient, hessian, x, opt, "angle " + std::to_string(angle));
    }
}

TEST(EdgeEdgeMollifier, ThresholdAndItsRestPositionGradient)
{
    // eps_x = 1e-3 |a|^2 |b|^2 is a polynomial of degree 4: generic tolerance.
    RandomPoints random(82);
    for (int k = 0; k < 20; ++k) {
        const Vec<12> rest = stack(random(), random(), random(), random());
        const Eigen::Vector3d a = vertex(rest, 1) - vertex(rest, 0), b = vertex(rest, 3) - vertex(rest, 2);
        EXPECT_NEAR(threshold_of(rest), 1e-3 * a.squaredNorm() * b.squaredNorm(), 1e-18);
        const Vec<12> g = edge_edge_mollifier_threshold_gradient(
            vertex(rest, 0), vertex(rest, 1), vertex(rest, 2), vertex(rest, 3));
        const FdReport r = compare_fd(
            g, [&](double h) { return fd_gradient<12>(threshold_of, rest, h); }, fd_steps(), 1e-300);
        EXPECT_LE(r.best, 1e-7) << r.table();
        EXPECT_TRUE(r.second_order()) << r.table();
    }
}

TEST(EdgeEdgeMollifier, ScalarDerivativesInXAndEpsX)
{
    // m is a quadratic in x below eps_x and (2 - x/e)(x/e) is smooth in
    // e > 0: the central differences below are exact up to round-off or
    // O(h^2) truncation, so 1e-7 relative is a tight check.
    for (double eps_x : { 1e-3, 2.5e-7, 1e-12 }) {
        for (double s : { 0.0, 0.1, 0.5, 0.9, 0.999 }) {
            const double x = s * eps_x;
            SCOPED_TRACE("eps_x " + std::to_string(eps_x) + ", x / eps_x " + std::to_string(s));
            const double h_scale = eps_x * 1e-3 * (s < 0.99 ? 1 : 0.1); // stay below eps_x
            EXPECT_NEAR(edge_edge_mollifier(x, eps_x), (2 - s) * s, 1e-15);
            if (s > 0) {
                EXPECT_LE(best_relative_error_1d([&](double y) { return edge_edge_mollifier(y, eps_x); }, x,
                              edge_edge_mollifier_gradient(x, eps_x), h_scale),
                    1e-7);
            }
            EXPECT_LE(best_relative_error_1d([&](double y) { return edge_edge_mollifier_gradient(y, eps_x); }, x,
                          edge_edge_mollifier_hessian(x, eps_x), h_scale),
                1e-7);
            if (s > 0) {
                // d/d eps_x; moving eps_x up keeps x below it.
                EXPECT_LE(best_relative_error_1d([&](double e) { return edge_edge_mollifier(x, e); }, eps_x,
                              edge_edge_mollifier_gradient_wrt_eps_x(x, eps_x), h_scale),
                    1e-7);
                EXPECT_LT(edge_edge_mollifier_gradient_wrt_eps_x(x, eps_x), 0)
                    << "a larger threshold must mollify more (lower m)";
            }
            if (std::abs(2 * s - 1) > 1e-12) {
                EXPECT_LE(best_relative_error_1d([&](double e) { return edge_edge_mollifier_gradient(x, e); }, eps_x,
                              edge_edge_mollifier_gradient_jacobian_wrt_eps_x(x, eps_x), h_scale),
                    1e-7);
            } else {
                EXPECT_EQ(edge_edge_mollifier_gradient_jacobian_wrt_eps_x(x, eps_x), 0);
            }
        }
        // Unmollified side: m = 1 and every derivative vanishes.
        for (double s : { 1.0, 1.5, 1e6 }) {
            EXPECT_EQ(edge_edge_mollifier(s * eps_x, eps_x), 1);
            EXPECT_EQ(edge_edge_mollifier_gradient(s * eps_x, eps_x), 0);
            EXPECT_EQ(edge_edge_mollifier_hessian(s * eps_x, eps_x), 0);
            EXPECT_EQ(edge_edge_mollifier_gradient_wrt_eps_x(s * eps_x, eps_x), 0);
            EXPECT_EQ(edge_edge_mollifier_gradient_jacobian_wrt_eps_x(s * eps_x, eps_x), 0);
        }
    }
    // A degenerate rest edge gives eps_x = 0: unmollified, no division by zero.
    EXPECT_EQ(edge_edge_mollifier(0.0, 0.0), 1);
    EXPECT_EQ(edge_edge_mollifier_gradient(0.0, 0.0), 0);
}

TEST(EdgeEdgeMollifier, ContinuousAndC1AtTheThreshold)
{
    // m(eps_x (1 - delta)) = 1 - delta^2 and m'(eps_x (1 - delta)) = 2 delta / eps_x:
    // value and slope both tend to the unmollified side (1, 0); the second
    // derivative jumps from -2 / eps_x^2 to 0 (m is C1, not C2).
    for (double eps_x : { 1e-3, 1e-10 }) {
        for (double delta : { 1e-2, 1e-4, 1e-6 }) {
            const double x = eps_x * (1 - delta);
            EXPECT_NEAR(edge_edge_mollifier(x, eps_x), 1 - delta * delta, 1e-15);
            EXPECT_NEAR(edge_edge_mollifier_gradient(x, eps_x) * eps_x, 2 * delta, 1e-12 * delta + 1e-15);
            EXPECT_NEAR(edge_edge_mollifier_gradient_wrt_eps_x(x, eps_x) * eps_x, -2 * delta * (1 - delta), 1e-12);
        }
        EXPECT_EQ(edge_edge_mollifier(eps_x, eps_x), 1);
        EXPECT_EQ(edge_edge_mollifier_gradient(eps_x, eps_x), 0);
        EXPECT_NEAR(edge_edge_mollifier_hessian(eps_x * (1 - 1e-9), eps_x) * eps_x * eps_x, -2, 1e-12);
    }
}

TEST(EdgeEdgeMollifier, PositionDerivativesMatchFiniteDifferences)
{
    // Nearly parallel pairs (x < 0.8 eps_x) with eps_x from a rest shape;
    // steps up to 1e-3 turn an edge by at most ~1.5e-3, which keeps x below
    // eps_x (where m'' jumps) for angles up to 0.02. m is a polynomial in the
    // positions there: generic tolerance and order. At exactly parallel
    // edges the gradient vanishes (floor 1: absolute errors against the
    // Hessian m'(0) hess x).
    RandomPoints random(84);
    for (double angle : { 0.0, 1e-4, 0.01, 0.02 }) {
        for (int k = 0; k < 3; ++k) {
            const Vec<12> x = edge_pair(angle, 1.0, 0.8, random);
            const Vec<12> rest = x + 0.05 * stack(random(), random(), random(), random());
            const double eps_x = threshold_of(rest);
            const auto value = [&](const Vec<12>& y) {
                return edge_edge_mollifier(vertex(y, 0), vertex(y, 1), vertex(y, 2), vertex(y, 3), eps_x);
            };
            const auto gradient = [&](const Vec<12>& y) {
                return edge_edge_mollifier_gradient(vertex(y, 0), vertex(y, 1), vertex(y, 2), vertex(y, 3), eps_x);
            };
            const auto hessian = [&](const Vec<12>& y) {
                return edge_edge_mollifier_hessian(vertex(y, 0), vertex(y, 1), vertex(y, 2), vertex(y, 3), eps_x);
            };
            ASSERT_LT(edge_edge_cross_squarednorm(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3)), 0.8 * eps_x);
            FdOptions opt;
            opt.step_scale = 0.1;
            opt.floor = angle == 0 ? 1 : 1e-300;
            expect_derivatives<12>(value, gradient, hessian, x, opt, "angle " + std::to_string(angle));
            EXPECT_LT(value(x), 1);
        }
    }
    // Far from parallel: m = 1, zero derivatives.
    const Vec<12> x = edge_pair(0.5, 1.0, 0.8, random);
    const double eps_x = threshold_of(x);
    EXPECT_EQ(edge_edge_mollifier(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3), eps_x), 1);
    EXPECT_EQ(
        edge_edge_mollifier_gradient(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3), eps_x), Vec<12>::Zero());
    EXPECT_EQ(
        edge_edge_mollifier_hessian(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3), eps_x), Mat<12>::Zero());
}

TEST(EdgeEdgeMollifier, DerivativesWithRespectToEpsXAndTheShapeDerivative)
{
    // dm/d eps_x and d(grad m)/d eps_x against central differences in eps_x
    // (steps 1e-3 eps_x and below keep x < eps_x), and the shape derivative
    // of m(x(positions), eps_x(rest)) with respect to the rest positions,
    // dm/d eps_x * d eps_x / d rest, against central differences in the rest
    // positions: the check a sign error in dm/d eps_x cannot pass.
    // All are smooth rational functions on these steps: 1e-7 relative.
    RandomPoints random(85);
    for (double angle : { 1e-3, 0.01, 0.02 }) {
        const Vec<12> x = edge_pair(angle, 0.9, 1.2, random);
        const Vec<12> rest = x + 0.05 * stack(random(), random(), random(), random());
        const double eps_x = threshold_of(rest);
        const Eigen::Vector3d ea0 = vertex(x, 0), ea1 = vertex(x, 1), eb0 = vertex(x, 2), eb1 = vertex(x, 3);
        SCOPED_TRACE("angle " + std::to_string(angle));

        const double dm_deps = edge_edge_mollifier_gradient_wrt_eps_x(ea0, ea1, eb0, eb1, eps_x);
        EXPECT_LT(dm_deps, 0);
        EXPECT_LE(best_relative_error_1d([&](double e) { return edge_edge_mollifier(ea0, ea1, eb0, eb1, e); }, eps_x,
                      dm_deps, eps_x * 1e-1),
            1e-7);

        const Vec<12> mixed = edge_edge_mollifier_gradient_jacobian_wrt_eps_x(ea0, ea1, eb0, eb1, eps_x);
        const FdReport r_mixed = compare_fd(
            mixed,
            [&](double h) -> Vec<12> {
                return (edge_edge_mollifier_gradient(ea0, ea1, eb0, eb1, eps_x + h)
                           - edge_edge_mollifier_gradient(ea0, ea1, eb0, eb1, eps_x - h))
                    / (2 * h);
            },
            fd_steps(eps_x * 1e-1), 1e-300);
        EXPECT_LE(r_mixed.best, 1e-7) << r_mixed.table();

        const Vec<12> shape = dm_deps
            * edge_edge_mollifier_threshold_gradient(
                vertex(rest, 0), vertex(rest, 1), vertex(rest, 2), vertex(rest, 3));
        const auto m_of_rest
            = [&](const Vec<12>& r) { return edge_edge_mollifier(ea0, ea1, eb0, eb1, threshold_of(r)); };
        const FdReport r_shape = compare_fd(
            shape, [&](double h) { return fd_gradient<12>(m_of_rest, rest, h); }, fd_steps(), 1e-300);
        EXPECT_LE(r_shape.best, 1e-7) << r_shape.table();
        EXPECT_TRUE(r_shape.second_order()) << r_shape.table();
    }
}
