// Closest-feature classification, checked by code independent of it: the
// squared distance of the classified type is compared with a brute-force
// minimum over a fine sampling of the segment, triangle or pair of segments
// ([0,1] or [0,1]^2 in the parameters), on random and near-degenerate
// configurations. The classified value must not exceed the sampled minimum
// (beyond round-off) and must be within the sampling error below it.

#include "fd_check.hpp"
#include "forward/contact/distance/edge_edge.hpp"
#include "forward/contact/distance/point_edge.hpp"
#include "forward/contact/distance/point_triangle.hpp"

#include <Eigen/Geometry>

using namespace diffipc;
using namespace diffipc::test;

namespace {

struct Sampled {
    double minimum; ///< smallest squared distance over the samples
    double spacing; ///< upper bound on the distance from any point of the primitive(s) to the nearest sample
};

Sampled sample_point_edge(const Eigen::Vector3d& p, const Eigen::Vector3d& e0, const Eigen::Vector3d& e1, int n)
{
    double best = std::numeric_limits<double>::infinity();
    for (int i = 0; i <= n; ++i) {
        const double t = double(i) / n;
        best = std::min(best, (p - ((1 - t) * e0 + t * e1)).squaredNorm());
    }
    return { best, (e1 - e0).norm() / (2.0 * n) };
}

Sampled sample_point_triangle(
    const Eigen::Vector3d& p, const Eigen::Vector3d& t0, const Eigen::Vector3d& t1, const Eigen::Vector3d& t2, int n)
{
    double best = std::numeric_limits<double>::infinity();
    for (int i = 0; i <= n; ++i) {
        for (int j = 0; i + j <= n; ++j) {
            const double u = double(i) / n, v = double(j) / n;
            best = std::min(best, (p - ((1 - u - v) * t0 + u * t1 + v * t2)).squaredNorm());
        }
    }
    const double longest = std::max({ (t1 - t0).norm(), (t2 - t1).norm(), (t0 - t2).norm() });
    return { best, longest / n };
}

Sampled sample_edge_edge(const Eigen::Vector3d& ea0, const Eigen::Vector3d& ea1, const Eigen::Vector3d& eb0,
    const Eigen::Vector3d& eb1, int n)
{
    double best = std::numeric_limits<double>::infinity();
    for (int i = 0; i <= n; ++i) {
        const double s = double(i) / n;
        const Eigen::Vector3d a = (1 - s) * ea0 + s * ea1;
        for (int j = 0; j <= n; ++j) {
            const double t = double(j) / n;
            best = std::min(best, (a - ((1 - t) * eb0 + t * eb1)).squaredNorm());
        }
    }
    return { best, ((ea1 - ea0).norm() + (eb1 - eb0).norm()) / (2.0 * n) };
}

/// d <= sampled minimum + round-off, and sampled minimum - d <= sampling error:
/// with the minimizer within `spacing` of a sample, |x - y|^2 grows from d by
/// at most spacing^2 + 2 sqrt(d) spacing. Round-off: 1e-13 relative to the
/// squared size of the configuration (values are differences of O(size^2)).
void expect_consistent(double d, const Sampled& sampled, double size, const std::string& what)
{
    const double roundoff = 1e-13 * size * size;
    EXPECT_LE(d, sampled.minimum + roundoff) << what;
    const double sampling = sampled.spacing * sampled.spacing + 2 * std::sqrt(std::max(d, 0.0)) * sampled.spacing;
    EXPECT_GE(d, sampled.minimum - sampling - roundoff) << what;
    EXPECT_GE(d, 0) << what;
}

double size_of(std::initializer_list<Eigen::Vector3d> points)
{
    double s = 0;
    for (const Eigen::Vector3d& p : points)
        s = std::max(s, p.norm());
    return std::max(s, 1e-300);
}

} // namespace

TEST(DistanceType, PointEdgeAgreesWithSampling)
{
    RandomPoints random(91);
    for (int k = 0; k < 2000; ++k) {
        const double scale = k % 3 == 0 ? 1 : k % 3 == 1 ? 1e-3 : 1e3;
        const Eigen::Vector3d p = scale * 1.5 * random(), e0 = scale * random(), e1 = scale * random();
        expect_consistent(point_edge_distance(p, e0, e1), sample_point_edge(p, e0, e1, 2000), size_of({ p, e0, e1 }),
            "random " + std::to_string(k));
    }
}

TEST(DistanceType, PointEdgeNearDegenerate)
{
    RandomPoints random(92);
    for (int k = 0; k < 200; ++k) {
        const Eigen::Vector3d e0 = random(), e1 = random();
        const Eigen::Vector3d e = e1 - e0;
        Eigen::Vector3d n = random.direction();
        n = (n - n.dot(e.normalized()) * e.normalized()).normalized();
        const double t = random.uniform(-1, 2);
        const double offsets[] = { 0, 1e-12, 1e-6 };
        for (double offset : offsets) {
            const Eigen::Vector3d p = e0 + t * e + offset * n; // on the line, its extension, or just off it
            expect_consistent(point_edge_distance(p, e0, e1), sample_point_edge(p, e0, e1, 2000),
                size_of({ p, e0, e1 }), "t " + std::to_string(t));
        }
        // Projection exactly at an end point, and a zero-length edge.
        const Eigen::Vector3d q = e1 + 0.3 * n;
        expect_consistent(point_edge_distance(q, e0, e1), sample_point_edge(q, e0, e1, 2000), size_of({ q, e0, e1 }),
            "level with e1");
        EXPECT_DOUBLE_EQ(point_edge_distance(q, e0, e0), (q - e0).squaredNorm());
    }
}

TEST(DistanceType, PointTriangleAgreesWithSampling)
{
    RandomPoints random(93);
    for (int k = 0; k < 300; ++k) {
        const double scale = k % 3 == 0 ? 1 : k % 3 == 1 ? 1e-3 : 1e3;
        const Eigen::Vector3d p = scale * 1.5 * random(), t0 = scale * random(), t1 = scale * random(),
                              t2 = scale * random();
        expect_consistent(point_triangle_distance(p, t0, t1, t2), sample_point_triangle(p, t0, t1, t2, 200),
            size_of({ p, t0, t1, t2 }), "random " + std::to_string(k));
    }
}

TEST(DistanceType, PointTriangleNearDegenerate)
{
    // Points in the plane (inside and outside), 1e-12 above it, exactly above
    // corners and edges; slivers and collinear (zero-area) triangles.
    RandomPoints random(94);
    for (int k = 0; k < 60; ++k) {
        const Eigen::Vector3d t0 = random(), t1 = random();
        Eigen::Vector3d t2 = random();
        if (k % 4 == 1)
            t2 = t0 + random.uniform(-0.5, 1.5) * (t1 - t0) + 1e-9 * random.direction(); // sliver
        if (k % 4 == 2)
            t2 = t0 + 0.37 * (t1 - t0); // collinear (up to rounding)
        const Eigen::Vector3d n = (t1 - t0).cross(t2 - t0).normalized();
        const Eigen::Vector3d feet[]
            = { t0 + random.uniform(-0.5, 1) * (t1 - t0) + random.uniform(-0.5, 1) * (t2 - t0), t1, (t1 + t2) / 2 };
        for (const Eigen::Vector3d& foot : feet) {
            for (double height : { 0.0, 1e-12, 0.2 }) {
                const Eigen::Vector3d p = foot + height * (n.allFinite() ? n : Eigen::Vector3d::UnitZ());
                expect_consistent(point_triangle_distance(p, t0, t1, t2), sample_point_triangle(p, t0, t1, t2, 200),
                    size_of({ p, t0, t1, t2 }), "config " + std::to_string(k) + ", height " + std::to_string(height));
            }
        }
    }
}

TEST(DistanceType, EdgeEdgeAgreesWithSampling)
{
    RandomPoints random(95);
    for (int k = 0; k < 300; ++k) {
        const double scale = k % 3 == 0 ? 1 : k % 3 == 1 ? 1e-3 : 1e3;
        const Eigen::Vector3d ea0 = scale * random(), ea1 = scale * random(), eb0 = scale * random(),
                              eb1 = scale * random();
        expect_consistent(edge_edge_distance(ea0, ea1, eb0, eb1), sample_edge_edge(ea0, ea1, eb0, eb1, 300),
            size_of({ ea0, ea1, eb0, eb1 }), "random " + std::to_string(k));
    }
}

TEST(DistanceType, EdgeEdgeNearDegenerate)
{
    // Parallel and nearly parallel edges (angles 1e-3 .. 1e-9, overlapping
    // or not, coplanar or not), crossing edges 1e-12 apart, an end point on
    // the other edge, and a zero-length edge.
    RandomPoints random(96);
    for (int k = 0; k < 40; ++k) {
        const Eigen::Matrix3d R = random.rotation();
        const Eigen::Vector3d c = random();
        for (double angle : { 0.0, 1e-9, 1e-6, 1e-3 }) {
            for (double gap : { 0.0, 1e-12, 0.1 }) {
                const double shift = random.uniform(-2.5, 2.5), side = random.uniform(-0.2, 0.2);
                const Eigen::Vector3d d(std::cos(angle), std::sin(angle), 0);
                const Eigen::Vector3d ea0 = R * Eigen::Vector3d(-1, 0, 0) + c, ea1 = R * Eigen::Vector3d(1, 0, 0) + c;
                const Eigen::Vector3d mid(shift, side, gap);
                const Eigen::Vector3d eb0 = R * (mid - 0.8 * d) + c, eb1 = R * (mid + 0.8 * d) + c;
                expect_consistent(edge_edge_distance(ea0, ea1, eb0, eb1), sample_edge_edge(ea0, ea1, eb0, eb1, 300),
                    size_of({ ea0, ea1, eb0, eb1 }),
                    "angle " + std::to_string(angle) + ", gap " + std::to_string(gap) + ", shift "
                        + std::to_string(shift));
            }
        }
        // eb0 on edge a's interior, eb1 off it; and a zero-length edge b.
        const Eigen::Vector3d ea0 = random(), ea1 = random(), eb1 = random();
        const Eigen::Vector3d eb0 = ea0 + 0.4 * (ea1 - ea0);
        expect_consistent(edge_edge_distance(ea0, ea1, eb0, eb1), sample_edge_edge(ea0, ea1, eb0, eb1, 300),
            size_of({ ea0, ea1, eb0, eb1 }), "end point on edge");
        expect_consistent(edge_edge_distance(ea0, ea1, eb1, eb1), sample_edge_edge(ea0, ea1, eb1, eb1, 300),
            size_of({ ea0, ea1, eb1 }), "zero-length edge");
    }
}
