// Edge-edge squared distance: every closest-feature type's derivatives
// against central differences, the scatter into the 12-vector, the untyped
// functions' dispatch, C1 continuity where the type switches, and the
// near-degenerate cases: parallel edges, nearly parallel edges (angles
// 1e-3 .. 1e-6), and edges 1e-12 apart.

#include "fd_check.hpp"
#include "forward/contact/distance/edge_edge.hpp"
#include "forward/contact/distance/point_line.hpp"

using namespace diffipc;
using namespace diffipc::test;

namespace {

using EE = EdgeEdgeDistanceType;
const EE ALL_TYPES[]
    = { EE::EA0_EB0, EE::EA0_EB1, EE::EA1_EB0, EE::EA1_EB1, EE::EA_EB0, EE::EA_EB1, EE::EA0_EB, EE::EA1_EB, EE::EA_EB };

double value(const Vec<12>& x, EE type)
{
    return edge_edge_distance(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3), type);
}
Vec<12> gradient(const Vec<12>& x, EE type)
{
    return edge_edge_distance_gradient(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3), type);
}
Mat<12> hessian(const Vec<12>& x, EE type)
{
    return edge_edge_distance_hessian(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3), type);
}
EE classify(const Vec<12>& x)
{
    return edge_edge_distance_type(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3));
}

void expect_typed_derivatives(EE type, const Vec<12>& x, const FdOptions& opt, const std::string& what)
{
    expect_derivatives<12>([&](const Vec<12>& y) { return value(y, type); },
        [&](const Vec<12>& y) { return gradient(y, type); }, [&](const Vec<12>& y) { return hessian(y, type); }, x, opt,
        what + ", type " + std::to_string(int(type)));
}

void expect_same_value_and_gradient(const Vec<12>& x, EE a, EE b, const std::string& what)
{
    SCOPED_TRACE(what);
    const double scale = gradient(x, a).norm();
    EXPECT_NEAR(value(x, a), value(x, b), 1e-14);
    EXPECT_LE((gradient(x, a) - gradient(x, b)).norm(), 1e-12 * scale) << gradient(x, a).transpose() << "\n"
                                                                       << gradient(x, b).transpose();
}

/// Edge a = (-1, 0, 0)..(1, 0, 0); edge b of length 2 in the plane z = gap,
/// at `angle` to a, passing over (shift, 0) at its parameter `t_cross` (so
/// the closest points of the lines are at a's parameter (shift + 1) / 2 and
/// b's t_cross); then a random rigid motion.
Vec<12> edge_pair(double angle, double gap, double shift, RandomPoints& random, double t_cross = 0.5)
{
    const Eigen::Vector3d d(2 * std::cos(angle), 2 * std::sin(angle), 0);
    const Eigen::Vector3d eb0 = Eigen::Vector3d(shift, 0, gap) - t_cross * d;
    const Eigen::Matrix3d R = random.rotation();
    const Eigen::Vector3d t = random();
    return stack(Eigen::Vector3d(R * Eigen::Vector3d(-1, 0, 0) + t), Eigen::Vector3d(R * Eigen::Vector3d(1, 0, 0) + t),
        Eigen::Vector3d(R * eb0 + t), Eigen::Vector3d(R * (eb0 + d) + t));
}

} // namespace

TEST(EdgeEdgeDistance, EveryTypeMatchesFiniteDifferencesOnRandomConfigurations)
{
    // Each type is one smooth formula valid anywhere away from degeneracy
    // (line-line: away from parallel edges), so every type is checked at
    // every configuration.
    RandomPoints random(71);
    int tested = 0;
    while (tested < 20) {
        const Vec<12> x = stack(random(), random(), random(), random());
        const Eigen::Vector3d a = vertex(x, 1) - vertex(x, 0), b = vertex(x, 3) - vertex(x, 2);
        if (a.norm() < 0.3 || b.norm() < 0.3 || a.cross(b).norm() < 0.25 * a.norm() * b.norm())
            continue;
        for (EE type : ALL_TYPES)
            expect_typed_derivatives(type, x, {}, "config " + std::to_string(tested));
        ++tested;
    }
}

TEST(EdgeEdgeDistance, TypesScatterTheirSubDistance)
{
    // EA_EB1 is point-line(eb1, ea0, ea1): its (p, e0, e1) blocks land on (eb1, ea0, ea1).
    RandomPoints random(72);
    const Eigen::Vector3d ea0 = random(), ea1 = random(), eb0 = random(), eb1 = random();
    const Vec<12> g = edge_edge_distance_gradient(ea0, ea1, eb0, eb1, EE::EA_EB1);
    const Vec<9> g_line = point_line_distance_gradient(eb1, ea0, ea1);
    EXPECT_EQ(Eigen::Vector3d(g.segment<3>(9)), Eigen::Vector3d(g_line.segment<3>(0)));
    EXPECT_EQ(Eigen::Vector3d(g.segment<3>(0)), Eigen::Vector3d(g_line.segment<3>(3)));
    EXPECT_EQ(Eigen::Vector3d(g.segment<3>(3)), Eigen::Vector3d(g_line.segment<3>(6)));
    EXPECT_EQ(Eigen::Vector3d(g.segment<3>(6)), Eigen::Vector3d::Zero());
    const Mat<12> H = edge_edge_distance_hessian(ea0, ea1, eb0, eb1, EE::EA_EB1);
    const Mat<9> H_line = point_line_distance_hessian(eb1, ea0, ea1);
    EXPECT_EQ(Eigen::Matrix3d(H.block<3, 3>(9, 3)), Eigen::Matrix3d(H_line.block<3, 3>(0, 6)));
    EXPECT_EQ((H.block<3, 12>(6, 0).norm()), 0);
}

TEST(EdgeEdgeDistance, UntypedFunctionsUseTheClassification)
{
    RandomPoints random(73);
    for (int k = 0; k < 100; ++k) {
        const Vec<12> x = stack(random(), random(), random(), random());
        const EE type = classify(x);
        const Eigen::Vector3d ea0 = vertex(x, 0), ea1 = vertex(x, 1), eb0 = vertex(x, 2), eb1 = vertex(x, 3);
        EXPECT_EQ(edge_edge_distance(ea0, ea1, eb0, eb1), value(x, type));
        EXPECT_EQ(edge_edge_distance_gradient(ea0, ea1, eb0, eb1), gradient(x, type));
        EXPECT_EQ(edge_edge_distance_hessian(ea0, ea1, eb0, eb1), hessian(x, type));
    }
}

TEST(EdgeEdgeDistance, ContinuousGradientWhereTheTypeSwitches)
{
    // With the closest points exactly at an end point of one edge (shift
    // puts the crossing at ea1, at eb0, or at ea0 and eb1), line-line,
    // point-line and point-point agree in value and gradient: the minimum over the
    // segments' parameters is C1 in the vertices (envelope theorem).
    RandomPoints random(74);
    const double angle = 0.7, gap = 0.2;
    for (int k = 0; k < 5; ++k) {
        Vec<12> x = edge_pair(angle, gap, 1.0, random);
        expect_same_value_and_gradient(x, EE::EA_EB, EE::EA1_EB, "crossing at ea1");
        expect_same_value_and_gradient(x, EE::EA_EB, classify(x), "crossing at ea1, classified");
        x = edge_pair(angle, gap, 0.2, random, 0.0);
        expect_same_value_and_gradient(x, EE::EA_EB, EE::EA_EB0, "crossing at eb0");
        expect_same_value_and_gradient(x, EE::EA_EB, classify(x), "crossing at eb0, classified");
        x = edge_pair(angle, gap, -1.0, random, 1.0);
        expect_same_value_and_gradient(x, EE::EA_EB, EE::EA0_EB, "crossing at ea0 and eb1");
        expect_same_value_and_gradient(x, EE::EA_EB, EE::EA_EB1, "crossing at ea0 and eb1");
        expect_same_value_and_gradient(x, EE::EA_EB, EE::EA0_EB1, "crossing at ea0 and eb1");
        expect_same_value_and_gradient(x, EE::EA_EB, classify(x), "crossing at ea0 and eb1, classified");
    }
}

TEST(EdgeEdgeDistance, ParallelEdges)
{
    // Exactly parallel edges: the line-line type is undefined, so the
    // classifier must pick an end-point type, whose derivatives are smooth:
    // generic tolerance. Floor 1 keeps an exactly zero gradient testable.
    RandomPoints random(75);
    for (double shift : { 0.0, 0.5, 1.5, 2.5, -3.0 }) {
        for (double gap : { 0.1, 1e-6 }) {
            const Vec<12> x = edge_pair(0.0, gap, shift, random);
            const EE type = classify(x);
            EXPECT_NE(type, EE::EA_EB) << "shift " << shift;
            const double expected = gap * gap + std::pow(std::max(0.0, std::abs(shift) - 2), 2);
            EXPECT_NEAR(value(x, type), expected, 1e-12) << "shift " << shift;
            FdOptions opt;
            opt.floor = 1;
            opt.check_order = false; // point-point types are exact quadratics: FD has no truncation error
            expect_typed_derivatives(type, x, opt, "parallel, shift " + std::to_string(shift));
        }
    }
}

TEST(EdgeEdgeDistance, NearlyParallelEdges)
{
    // Overlapping edges at small angles: for a centred crossing the closest
    // points are interior (line-line), beyond an end point that end point
    // meets the other edge (point-line). Line-line derivatives vary over
    // lengths ~angle and are checked with steps and tolerance (1e-10 / angle)
    // as in test_line_line.cpp, where the choice is explained; the other
    // types are smooth on unit scales and get the generic tolerance.
    RandomPoints random(76);
    for (double angle : { 1e-3, 1e-4, 1e-5, 1e-6 }) {
        for (double shift : { 0.0, 0.3, 1.7 }) {
            const Vec<12> x = edge_pair(angle, 0.1, shift, random);
            const EE type = classify(x);
            if (shift == 0.0) {
                EXPECT_EQ(type, EE::EA_EB) << "angle " << angle;
            }
            // Beyond ea1 (shift > 1) ea1 is closest, offset 0.7 sin(angle) from line b.
            const double offset = std::max(0.0, shift - 1) * std::sin(angle);
            EXPECT_NEAR(value(x, type), 0.01 + offset * offset, 1e-15) << "angle " << angle << ", shift " << shift;
            FdOptions opt;
            if (type == EE::EA_EB) {
                opt.gradient_tolerance = opt.hessian_tolerance = 1e-10 / angle;
                opt.step_scale = angle;
            }
            expect_typed_derivatives(
                type, x, opt, "angle " + std::to_string(angle) + ", shift " + std::to_string(shift));
        }
    }
}

TEST(EdgeEdgeDistance, EdgesWithinTinyOffsets)
{
    // Crossing edges and end points 1e-12 apart. The gap is resolved to
    // ~1e-16 by O(1) coordinates, so the gradient (proportional to the gap)
    // is known to ~1e-4 relative: 1e-3. The O(1) Hessian keeps 1e-7; O(1)
    // third derivatives need steps down to 1e-10.
    RandomPoints random(77);
    for (double shift : { 0.0, 0.6, 1.0 }) {
        const Vec<12> x = edge_pair(0.5, 1e-12, shift, random);
        FdOptions opt;
        opt.gradient_tolerance = 1e-3;
        opt.check_order = false;
        opt.step_scale = 1e-3;
        expect_typed_derivatives(classify(x), x, opt, "gap 1e-12, shift " + std::to_string(shift));
        EXPECT_NEAR(std::sqrt(value(x, classify(x))), 1e-12, 1e-15);
    }
}
