// Point-edge squared distance: every closest-feature type's derivatives
// against central differences, the scatter into the 9-vector, the untyped
// functions' dispatch, C1 continuity where the type switches, points on the
// edge's extension and 1e-12 from an end point, and 2D inputs.

#include "fd_check.hpp"
#include "forward/contact/distance/point_edge.hpp"
#include "forward/contact/distance/point_line.hpp"
#include "forward/contact/distance/point_point.hpp"

using namespace diffipc;
using namespace diffipc::test;

namespace {

using PE = PointEdgeDistanceType;
const PE ALL_TYPES[] = { PE::P_E0, PE::P_E1, PE::P_E };

struct Typed {
    PE type;
    double operator()(const Vec<9>& x) const
    {
        return point_edge_distance(vertex(x, 0), vertex(x, 1), vertex(x, 2), type);
    }
    Vec<9> gradient(const Vec<9>& x) const
    {
        return point_edge_distance_gradient(vertex(x, 0), vertex(x, 1), vertex(x, 2), type);
    }
    Mat<9> hessian(const Vec<9>& x) const
    {
        return point_edge_distance_hessian(vertex(x, 0), vertex(x, 1), vertex(x, 2), type);
    }
};

void expect_typed_derivatives(PE type, const Vec<9>& x, const FdOptions& opt, const std::string& what)
{
    const Typed t { type };
    expect_derivatives<9>(
        t, [&](const Vec<9>& y) { return t.gradient(y); }, [&](const Vec<9>& y) { return t.hessian(y); }, x, opt,
        what + ", type " + std::to_string(int(type)));
}

PE classify(const Vec<9>& x) { return point_edge_distance_type(vertex(x, 0), vertex(x, 1), vertex(x, 2)); }

} // namespace

TEST(PointEdgeDistance, EveryTypeMatchesFiniteDifferencesOnRandomConfigurations)
{
    // Each type is one smooth formula valid anywhere (away from a degenerate
    // edge), so every type is checked at every configuration, not only where
    // the classifier would pick it.
    RandomPoints random(51);
    for (int k = 0; k < 30; ++k) {
        const Vec<9> x = stack(random(), random(), random());
        if ((vertex(x, 2) - vertex(x, 1)).norm() < 0.3)
            continue;
        for (PE type : ALL_TYPES)
            expect_typed_derivatives(type, x, {}, "config " + std::to_string(k));
    }
}

TEST(PointEdgeDistance, TypesScatterTheirSubDistance)
{
    RandomPoints random(52);
    const Eigen::Vector3d p = random(), e0 = random(), e1 = random();
    const Vec<9> g0 = point_edge_distance_gradient(p, e0, e1, PE::P_E0);
    EXPECT_EQ(g0.head<6>(), point_point_distance_gradient(p, e0));
    EXPECT_EQ(g0.tail<3>(), Eigen::Vector3d::Zero());
    const Vec<9> g1 = point_edge_distance_gradient(p, e0, e1, PE::P_E1);
    EXPECT_EQ(g1.head<3>(), point_point_distance_gradient(p, e1).head<3>());
    EXPECT_EQ(g1.segment<3>(3), Eigen::Vector3d::Zero());
    EXPECT_EQ(g1.tail<3>(), point_point_distance_gradient(p, e1).tail<3>());
    const Mat<9> H1 = point_edge_distance_hessian(p, e0, e1, PE::P_E1);
    EXPECT_EQ(
        Eigen::Matrix3d(H1.block<3, 3>(0, 6)), Eigen::Matrix3d(point_point_distance_hessian(p, e1).block<3, 3>(0, 3)));
    EXPECT_EQ(H1.row(4).norm(), 0);
    EXPECT_EQ(point_edge_distance_gradient(p, e0, e1, PE::P_E), point_line_distance_gradient(p, e0, e1));
}

TEST(PointEdgeDistance, UntypedFunctionsUseTheClassification)
{
    RandomPoints random(53);
    for (int k = 0; k < 100; ++k) {
        const Eigen::Vector3d p = 2 * random(), e0 = random(), e1 = random();
        const PE type = point_edge_distance_type(p, e0, e1);
        EXPECT_EQ(point_edge_distance(p, e0, e1), point_edge_distance(p, e0, e1, type));
        EXPECT_EQ(point_edge_distance_gradient(p, e0, e1), point_edge_distance_gradient(p, e0, e1, type));
        EXPECT_EQ(point_edge_distance_hessian(p, e0, e1), point_edge_distance_hessian(p, e0, e1, type));
    }
}

TEST(PointEdgeDistance, ContinuousGradientWhereTheTypeSwitches)
{
    // Where the projection of p falls exactly on an end point, the
    // point-point and point-line formulas give the same value and gradient
    // (the squared distance is C1 there; only the Hessian jumps).
    RandomPoints random(54);
    for (int k = 0; k < 20; ++k) {
        const Eigen::Vector3d e0 = random(), e1 = random();
        const Eigen::Vector3d e = (e1 - e0).normalized();
        Eigen::Vector3d n = random.direction();
        n = (n - n.dot(e) * e).normalized();
        for (int end = 0; end < 2; ++end) {
            const Eigen::Vector3d p = (end ? e1 : e0) + random.uniform(0.1, 1) * n;
            const PE point_type = end ? PE::P_E1 : PE::P_E0;
            const double scale = point_edge_distance_gradient(p, e0, e1, PE::P_E).norm();
            EXPECT_NEAR(point_edge_distance(p, e0, e1, point_type), point_edge_distance(p, e0, e1, PE::P_E), 1e-14);
            EXPECT_LE(
                (point_edge_distance_gradient(p, e0, e1, point_type) - point_edge_distance_gradient(p, e0, e1, PE::P_E))
                    .norm(),
                1e-13 * scale);
        }
    }
}

TEST(PointEdgeDistance, PointOnTheEdgesExtension)
{
    // The classifier must pick the end point; the point-line formula (zero
    // there) must still have finite derivatives. Floor 1: absolute errors
    // against the O(1) Hessian when the gradient vanishes.
    const Eigen::Vector3d e0(0.2, -0.1, 0.4), e1(-0.5, 0.6, 0.1);
    for (double t : { -1.0, -1e-3, 1 + 1e-3, 2.0 }) {
        const Vec<9> x = stack(Eigen::Vector3d(e0 + t * (e1 - e0)), e0, e1);
        const PE type = classify(x);
        EXPECT_EQ(type, t < 0 ? PE::P_E0 : PE::P_E1) << "t = " << t;
        FdOptions opt;
        opt.floor = 1;
        expect_typed_derivatives(type, x, opt, "t = " + std::to_string(t));
        expect_typed_derivatives(PE::P_E, x, opt, "point-line on the extension, t = " + std::to_string(t));
    }
}

TEST(PointEdgeDistance, PointWithinTinyOffsetsOfAnEndPointOrTheEdge)
{
    // The offset 1e-12 is resolved to ~1e-16 by O(1) coordinates, so the
    // gradient (proportional to the offset) is known to ~1e-4 relative: 1e-3.
    // The O(1) Hessian keeps 1e-7; O(1) third derivatives need steps to 1e-10.
    RandomPoints random(55);
    for (int k = 0; k < 20; ++k) {
        const Eigen::Vector3d e0 = random(), e1 = random();
        const Eigen::Vector3d base = k % 3 == 0 ? e0 : k % 3 == 1 ? e1 : Eigen::Vector3d(0.4 * e0 + 0.6 * e1);
        const Vec<9> x = stack(Eigen::Vector3d(base + 1e-12 * random.direction()), e0, e1);
        FdOptions opt;
        opt.gradient_tolerance = 1e-3;
        opt.check_order = false;
        opt.step_scale = 1e-3;
        expect_typed_derivatives(classify(x), x, opt, "config " + std::to_string(k));
    }
}

TEST(PointEdgeDistance, TwoDimensionalInputsKeepZeroZDerivatives)
{
    RandomPoints random(56);
    for (int k = 0; k < 20; ++k) {
        Eigen::Vector3d p = random(), e0 = random(), e1 = random();
        p.z() = e0.z() = e1.z() = 0;
        const Vec<9> g = point_edge_distance_gradient(p, e0, e1);
        const Mat<9> H = point_edge_distance_hessian(p, e0, e1);
        for (int v = 0; v < 3; ++v) {
            EXPECT_EQ(g[3 * v + 2], 0);
            for (int w = 0; w < 3; ++w) // no coupling of z with x or y
                EXPECT_TRUE(H(3 * v + 2, 3 * w) == 0 && H(3 * v + 2, 3 * w + 1) == 0);
        }
    }
}
