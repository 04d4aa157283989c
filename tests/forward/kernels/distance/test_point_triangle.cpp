// Point-triangle squared distance: every closest-feature type's derivatives
// against central differences, the scatter into the 12-vector, the untyped
// functions' dispatch, C1 continuity where the type switches (point exactly
// above a corner or an edge, or level with a corner), and points 1e-12 from
// a corner, an edge or the face.

#include "fd_check.hpp"
#include "forward/contact/distance/point_line.hpp"
#include "forward/contact/distance/point_triangle.hpp"

using namespace diffipc;
using namespace diffipc::test;

namespace {

using PT = PointTriangleDistanceType;
const PT ALL_TYPES[] = { PT::P_T0, PT::P_T1, PT::P_T2, PT::P_E0, PT::P_E1, PT::P_E2, PT::P_T };

double value(const Vec<12>& x, PT type)
{
    return point_triangle_distance(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3), type);
}
Vec<12> gradient(const Vec<12>& x, PT type)
{
    return point_triangle_distance_gradient(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3), type);
}
Mat<12> hessian(const Vec<12>& x, PT type)
{
    return point_triangle_distance_hessian(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3), type);
}
PT classify(const Vec<12>& x)
{
    return point_triangle_distance_type(vertex(x, 0), vertex(x, 1), vertex(x, 2), vertex(x, 3));
}

void expect_typed_derivatives(PT type, const Vec<12>& x, const FdOptions& opt, const std::string& what)
{
    expect_derivatives<12>([&](const Vec<12>& y) { return value(y, type); },
        [&](const Vec<12>& y) { return gradient(y, type); }, [&](const Vec<12>& y) { return hessian(y, type); }, x, opt,
        what + ", type " + std::to_string(int(type)));
}

/// Angles above ~15 degrees and sides above 0.3.
bool well_shaped(const Vec<12>& x)
{
    const Eigen::Vector3d a = vertex(x, 2) - vertex(x, 1), b = vertex(x, 3) - vertex(x, 1),
                          c = vertex(x, 3) - vertex(x, 2);
    const double longest = std::max({ a.norm(), b.norm(), c.norm() });
    const double shortest = std::min({ a.norm(), b.norm(), c.norm() });
    return a.cross(b).norm() > 0.25 * longest * longest && shortest > 0.3;
}

/// A fixed well-shaped triangle, its unit normal, and the unit in-plane
/// outward normals of its edges E0 = (t0, t1), E1 = (t1, t2), E2 = (t2, t0).
struct Triangle {
    Eigen::Vector3d t[3] = { { 0.1, 0.2, -0.1 }, { 1.0, 0.3, 0.2 }, { 0.3, 1.1, 0.4 } };
    Eigen::Vector3d n = (t[1] - t[0]).cross(t[2] - t[0]).normalized();
    Eigen::Vector3d outward(int edge) const { return (t[(edge + 1) % 3] - t[edge]).cross(n).normalized(); }
    Vec<12> with(const Eigen::Vector3d& p) const { return stack(p, t[0], t[1], t[2]); }
};

/// The squared distance is C1 across a type switch: both types must agree
/// in value and gradient there.
void expect_same_value_and_gradient(const Vec<12>& x, PT a, PT b, const std::string& what)
{
    SCOPED_TRACE(what);
    const double scale = gradient(x, a).norm();
    EXPECT_NEAR(value(x, a), value(x, b), 1e-14);
    EXPECT_LE((gradient(x, a) - gradient(x, b)).norm(), 1e-13 * scale) << gradient(x, a).transpose() << "\n"
                                                                       << gradient(x, b).transpose();
}

} // namespace

TEST(PointTriangleDistance, EveryTypeMatchesFiniteDifferencesOnRandomConfigurations)
{
    // Each type is one smooth formula valid anywhere (away from degenerate
    // triangles), so every type is checked at every configuration.
    RandomPoints random(61);
    int tested = 0;
    while (tested < 20) {
        const Vec<12> x = stack(random(), random(), random(), random());
        if (!well_shaped(x))
            continue;
        for (PT type : ALL_TYPES)
            expect_typed_derivatives(type, x, {}, "config " + std::to_string(tested));
        ++tested;
    }
}

TEST(PointTriangleDistance, TypesScatterTheirSubDistance)
{
    // E2 = (t2, t0): the point-line gradient in (p, t2, t0) lands on (p, t2, t0).
    RandomPoints random(62);
    const Eigen::Vector3d p = random(), t0 = random(), t1 = random(), t2 = random();
    const Vec<12> g = point_triangle_distance_gradient(p, t0, t1, t2, PT::P_E2);
    const Vec<9> g_line = point_line_distance_gradient(p, t2, t0);
    EXPECT_EQ(Eigen::Vector3d(g.segment<3>(0)), Eigen::Vector3d(g_line.segment<3>(0)));
    EXPECT_EQ(Eigen::Vector3d(g.segment<3>(9)), Eigen::Vector3d(g_line.segment<3>(3)));
    EXPECT_EQ(Eigen::Vector3d(g.segment<3>(3)), Eigen::Vector3d(g_line.segment<3>(6)));
    EXPECT_EQ(Eigen::Vector3d(g.segment<3>(6)), Eigen::Vector3d::Zero());
    const Mat<12> H = point_triangle_distance_hessian(p, t0, t1, t2, PT::P_E2);
    const Mat<9> H_line = point_line_distance_hessian(p, t2, t0);
    EXPECT_EQ(Eigen::Matrix3d(H.block<3, 3>(9, 3)), Eigen::Matrix3d(H_line.block<3, 3>(3, 6)));
    EXPECT_EQ(H.row(7).norm(), 0);
    EXPECT_EQ(H.col(8).norm(), 0);
}

TEST(PointTriangleDistance, UntypedFunctionsUseTheClassification)
{
    RandomPoints random(63);
    for (int k = 0; k < 100; ++k) {
        const Vec<12> x = stack(Eigen::Vector3d(2 * random()), random(), random(), random());
        const PT type = classify(x);
        const Eigen::Vector3d p = vertex(x, 0), t0 = vertex(x, 1), t1 = vertex(x, 2), t2 = vertex(x, 3);
        EXPECT_EQ(point_triangle_distance(p, t0, t1, t2), value(x, type));
        EXPECT_EQ(point_triangle_distance_gradient(p, t0, t1, t2), gradient(x, type));
        EXPECT_EQ(point_triangle_distance_hessian(p, t0, t1, t2), hessian(x, type));
    }
}

TEST(PointTriangleDistance, ExactlyAboveACornerOrAnEdge)
{
    // Both neighbouring types are smooth there, so each matches central
    // differences with the generic tolerance, and they agree in value and
    // gradient (C1 across the switch). The classifier may pick any type that
    // meets there (above a corner, round-off can also select an edge through
    // it), so its choice is checked by value and gradient, not by name.
    const Triangle tri;
    const PT corner_types[] = { PT::P_T0, PT::P_T1, PT::P_T2 };
    const PT edge_types[] = { PT::P_E0, PT::P_E1, PT::P_E2 };
    for (double height : { 0.3, -0.05 }) {
        for (int i = 0; i < 3; ++i) {
            const Vec<12> above_corner = tri.with(tri.t[i] + height * tri.n);
            expect_same_value_and_gradient(above_corner, PT::P_T, classify(above_corner), "above corner, classified");
            expect_same_value_and_gradient(above_corner, PT::P_T, corner_types[i], "above corner");
            expect_typed_derivatives(PT::P_T, above_corner, {}, "above corner");
            expect_typed_derivatives(corner_types[i], above_corner, {}, "above corner");

            const Vec<12> above_edge = tri.with(0.6 * tri.t[i] + 0.4 * tri.t[(i + 1) % 3] + height * tri.n);
            expect_same_value_and_gradient(above_edge, PT::P_T, classify(above_edge), "above edge, classified");
            expect_same_value_and_gradient(above_edge, PT::P_T, edge_types[i], "above edge");
            expect_typed_derivatives(PT::P_T, above_edge, {}, "above edge");
            expect_typed_derivatives(edge_types[i], above_edge, {}, "above edge");

            // Outside edge i, level with its start corner: edge and corner types meet.
            const Vec<12> level = tri.with(tri.t[i] + 0.4 * tri.outward(i) + height * tri.n);
            expect_same_value_and_gradient(level, corner_types[i], classify(level), "level with corner, classified");
            expect_same_value_and_gradient(level, edge_types[i], corner_types[i], "level with corner");
        }
    }
}

TEST(PointTriangleDistance, PointWithinTinyOffsetsOfACornerAnEdgeOrTheFace)
{
    // The offset 1e-12 is resolved to ~1e-16 by O(1) coordinates, so the
    // gradient (proportional to the offset) is known to ~1e-4 relative: 1e-3.
    // The O(1) Hessian keeps 1e-7; O(1) third derivatives need steps to 1e-10.
    const Triangle tri;
    RandomPoints random(64);
    const Eigen::Vector3d targets[] = { tri.t[0], tri.t[2], 0.5 * (tri.t[1] + tri.t[2]),
        0.3 * tri.t[0] + 0.7 * tri.t[2], (tri.t[0] + tri.t[1] + tri.t[2]) / 3 };
    for (const Eigen::Vector3d& target : targets) {
        for (int k = 0; k < 3; ++k) {
            const Vec<12> x = tri.with(target + 1e-12 * random.direction());
            FdOptions opt;
            opt.gradient_tolerance = 1e-3;
            opt.check_order = false;
            opt.step_scale = 1e-3;
            expect_typed_derivatives(classify(x), x, opt, "offset 1e-12");
            EXPECT_NEAR(std::sqrt(value(x, classify(x))), 0, 1.01e-12);
        }
    }
}
