// Finite-difference checks of the lagged friction potential for every contact
// kind, at tangential displacements below, at and above eps, and its basic
// properties (zero at rest, PSD, force opposing slip).

#include "../../potential_fd.hpp"

#include "forward/contact/contact_potential.hpp"
#include "forward/contact/distance/distance_type.hpp"
#include "forward/contact/friction/friction_potential.hpp"
#include "forward/simulation/simulator.hpp"
#include "forward/solver/sparse_assembler.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

using namespace diffipc;
using nlohmann::json;

namespace {

/// Central differences of value -> gradient and gradient -> Hessian along random directions at x.
test::PotentialFD fd_check(const FrictionPotential& D, const Simulator& sim, const VectorXd& x, double h)
{
    // The Hessian's natural size, mu lambda / eps summed over contacts: in 2D beyond
    // eps (|u| in 1D) the true Hessian is exactly zero, so errors are measured
    // against this scale rather than against |H p|.
    double scale = 0;
    for (const auto& c : D.lagged())
        scale += c.coefficient * c.normal_force / D.eps();
    return test::potential_fd(D, sim.mesh(), sim.scene().dim, x, h, scale);
}

/// Lagged friction at a resting contact state of scene s, then slides the
/// first body tangentially by `slip` (m) along `direction`.
std::set<std::pair<int, int>> check_scene(const json& s, const VectorXd& direction, int expected_kinds_mask)
{
    std::set<std::pair<int, int>> types;
    Simulator sim(test::make_scene(s));
    const int d = sim.scene().dim;
    const VectorXd x0 = sim.positions();
    std::vector<double> mu(sim.scene().bodies.size() + sim.scene().obstacles.size(), 0.5);
    FrictionPotential D(d, mu, sim.mesh().vertex_body, /*eps_v=*/1e-3);
    const double dt = 0.01;
    D.set_step(x0, dt);
    D.lag(*sim.contact(), x0);
    EXPECT_FALSE(D.lagged().empty());
    for (const Contact& c : sim.contact()->contacts(x0))
        types.insert({ int(c.kind), c.distance_type });
    int mask = 0;
    for (const auto& c : D.lagged())
        mask |= 1 << int(c.kind);
    EXPECT_EQ(mask & expected_kinds_mask, expected_kinds_mask) << "missing contact kinds: " << mask;
    double at_rest = 0; // f0(0) = eps/3 per contact
    for (const auto& c : D.lagged())
        at_rest += c.coefficient * c.normal_force * D.eps() / 3;
    EXPECT_NEAR(D.value(x0), at_rest, 1e-12 * at_rest);
    const double eps = D.eps();
    for (double slip : { 0.3 * eps, eps, 3 * eps, 30 * eps }) {
        // Body 0 slides along `direction`, body 1 by half as much across it, so that no
        // contact sits at u = 0 (there the gradient is C1 but not C2: |u| u / eps^2,
        // and central differences of the Hessian converge only linearly).
        VectorXd across = VectorXd::Zero(3);
        across << -direction[2], 0, direction[0];
        if (d == 2)
            across << 0.3, 0, 0;
        VectorXd x = x0;
        for (Index v = 0; v < sim.scene().body_vertices; ++v) {
            const VectorXd shift = sim.mesh().vertex_body[v] == 0 ? VectorXd(slip * direction.head(d))
                                                                  : VectorXd(-0.5 * slip * across.head(d));
            x.segment(v * d, d) += shift + 1e-3 * eps * test::random_vector(d, unsigned(v + 1));
        }
        // Steps well inside the smooth pieces; at y = eps, f1'' jumps (f1' is continuous), so central differences
        // of the gradient converge only linearly there and only the gradient is checked tightly.
        const double h = 1e-4 * eps;
        const test::PotentialFD e = fd_check(D, sim, x, h);
        std::printf("  slip %.1f eps: gradient %.2e, Hessian %.2e, min eigenvalue / |H| %.2e\n", slip / eps, e.gradient,
            e.hessian, e.min_eigenvalue);
        EXPECT_LT(e.gradient, 1e-6) << "slip " << slip / eps << " eps";
        if (slip != eps)
            EXPECT_LT(e.hessian, 1e-5) << "slip " << slip / eps << " eps";
        EXPECT_GT(e.min_eigenvalue, -1e-12);
        // Friction dissipates: the force -g opposes the motion, g . (x - x0) > 0.
        VectorXd g = VectorXd::Zero(x.size());
        D.add_gradient(x, 1.0, g);
        EXPECT_GT(g.dot(x - x0), 0);
    }
    return types;
}

} // namespace

TEST(FrictionPotential, F0IsC1AndF1IsItsDerivative)
{
    const double eps = 1e-3;
    for (double y : { 1e-6, 3e-4, 0.999e-3, 1.001e-3, 5e-3 }) {
        const double h = 1e-9;
        EXPECT_NEAR((FrictionPotential::f0(y + h, eps) - FrictionPotential::f0(y - h, eps)) / (2 * h),
            FrictionPotential::f1(y, eps), 1e-6);
        if (std::abs(y - eps) > 1e-6)
            EXPECT_NEAR((FrictionPotential::f1(y + h, eps) - FrictionPotential::f1(y - h, eps)) / (2 * h),
                FrictionPotential::f1_derivative(y, eps), 1e-4);
    }
    EXPECT_NEAR(FrictionPotential::f0(eps, eps), eps, 1e-18);
    EXPECT_NEAR(FrictionPotential::f1(eps, eps), 1.0, 1e-15);
}

TEST(FrictionPotential, FiniteDifferences2DVertexEdgeAndPlane)
{
    json s;
    s["dimension"] = 2;
    auto box = [](const std::string& name, std::vector<double> lo, std::vector<double> hi) {
        return test::box_body(name, lo, hi, std::vector<int> { 2, 1 });
    };
    // Body 0 rests within dhat on body 1 (vertex-edge) and on a plane (vertex-plane) at its left end.
    s["bodies"] = { box("top", { 0.25, 0.5004 }, { 1.25, 1.0 }), box("bottom", { 0, 0.0004 }, { 1, 0.5 }) };
    s["obstacles"] = { { { "plane", { { "point", { 0, 0 } }, { "normal", { 0, 1 } } } } } };
    s["contact"] = { { "dhat", 1e-3 }, { "kappa", 1e3 } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", 1 } };
    Eigen::VectorXd dir(3);
    dir << 1, 0, 0;
    check_scene(s, dir, (1 << int(ContactKind::VERTEX_EDGE)) | (1 << int(ContactKind::VERTEX_PLANE)));
}

TEST(FrictionPotential, FiniteDifferences3DVertexFaceEdgeEdgeAndPlane)
{
    json s;
    s["dimension"] = 3;
    auto box = [](const std::string& name, std::vector<double> lo, std::vector<double> hi) {
        return test::box_body(name, lo, hi, std::vector<int> { 2, 1, 2 });
    };
    // Body 0 rotated about y sits within dhat on body 1 (vertex-face and edge-edge); body 1 on a plane.
    s["bodies"]
        = { box("top", { 0.1, 0.5005, 0.1 }, { 0.9, 1.0, 0.9 }), box("bottom", { 0, 0.0005, 0 }, { 1, 0.5, 1 }) };
    s["bodies"][0]["rotation"] = { 0, 17, 0 };
    s["bodies"][0]["translation"] = { 0.1, 0, -0.05 };
    s["obstacles"] = { { { "plane", { { "point", { 0, 0, 0 } }, { "normal", { 0, 1, 0 } } } } } };
    s["contact"] = { { "dhat", 1e-3 }, { "kappa", 1e3 } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", 1 } };
    Eigen::VectorXd dir(3);
    dir << 0.8, 0, 0.6;
    const auto types = check_scene(s, dir,
        (1 << int(ContactKind::VERTEX_FACE)) | (1 << int(ContactKind::EDGE_EDGE))
            | (1 << int(ContactKind::VERTEX_PLANE)));
    // Point-triangle vertex-face types, and point-line / line-line edge-edge types.
    using PT = PointTriangleDistanceType;
    using EE = EdgeEdgeDistanceType;
    const int VF = int(ContactKind::VERTEX_FACE), EDGES = int(ContactKind::EDGE_EDGE);
    EXPECT_TRUE(types.count({ VF, int(PT::P_T) })) << "no point-triangle type";
    int edge_types = 0;
    for (EE t : { EE::EA_EB0, EE::EA_EB1, EE::EA0_EB, EE::EA1_EB, EE::EA_EB })
        edge_types += int(types.count({ EDGES, int(t) }));
    EXPECT_GT(edge_types, 0) << "no point-line or line-line edge-edge type";
}

TEST(FrictionPotential, ClosestPointWeightsReproduceTheDistance)
{
    // For every lagged contact, r = sum_i gamma_i x_i is the vector between the
    // closest points: |r| must equal the classified distance and r must be along
    // the stored normal. Slides a box over another in small steps so that vertices
    // cross edges and corners (every point-triangle and edge-edge type appears).
    json s;
    s["dimension"] = 3;
    auto box = [](const std::string& name, std::vector<double> lo, std::vector<double> hi, std::vector<int> cells) {
        return test::box_body(name, lo, hi, cells);
    };
    s["bodies"] = { box("top", { 0.3, 0.5004, 0.3 }, { 0.7, 0.7, 0.7 }, { 1, 1, 1 }),
        box("bottom", { 0, 0, 0 }, { 1, 0.5, 1 }, { 2, 1, 2 }) };
    s["bodies"][0]["rotation"] = { 0, 11, 0 };
    s["contact"] = { { "dhat", 1e-3 }, { "kappa", 1e3 } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", 1 } };
    Simulator sim(test::make_scene(s));
    const int d = 3;
    FrictionPotential D(d, std::vector<double>(2, 0.5), sim.mesh().vertex_body, 1e-3);
    std::set<std::pair<int, int>> seen;
    int checked = 0;
    for (double shift = -0.45; shift <= 0.45; shift += 0.0137) {
        VectorXd x = sim.positions();
        for (Index v = 0; v < sim.scene().body_vertices; ++v)
            if (sim.mesh().vertex_body[v] == 0) {
                x[v * d] += shift;
                x[v * d + 2] += 0.3 * shift;
            }
        D.lag(*sim.contact(), x);
        const ContactSet& set = sim.contact()->contacts(x);
        for (const Contact& c : set)
            seen.insert({ int(c.kind), c.distance_type });
        ASSERT_EQ(D.lagged().size(), set.size());
        for (size_t k = 0; k < set.size(); ++k) {
            const FrictionContact& f = D.lagged()[k];
            Eigen::Vector3d r = Eigen::Vector3d::Zero();
            for (int i = 0; i < f.num_vertices; ++i)
                r += f.weights[size_t(i)] * x.segment<3>(f.vertices[size_t(i)] * d);
            const double dist = std::sqrt(set[k].distance_squared);
            EXPECT_NEAR(r.norm(), dist, 1e-9 * dist + 1e-15)
                << "kind " << int(f.kind) << " type " << set[k].distance_type;
            EXPECT_NEAR(std::abs(r.normalized().dot(f.normal)), 1.0, 1e-9);
            EXPECT_LT((f.tangent.transpose() * f.normal).norm(), 1e-12);
            ++checked;
        }
    }
    std::printf("  %d lagged contacts checked, %zu (kind, type) combinations\n", checked, seen.size());
    // Point-triangle interior and edge types, and edge-edge line-line and point-line types.
    for (auto [kind, type] : std::vector<std::pair<int, int>> { { 1, 6 }, { 2, 8 } })
        EXPECT_TRUE(seen.count({ kind, type })) << kind << "/" << type;
    EXPECT_GE(seen.size(), 6u);
}

TEST(FrictionPotential, FiniteDifferencesLaggedAtClassificationSwitchPoints)
{
    // Lagged exactly where the closest-feature type switches: in 2D the top box's
    // vertices sit exactly above the bottom box's vertices (point-edge interior /
    // endpoint boundary), in 3D above the bottom box's edges and vertices.
    json s;
    s["dimension"] = 2;
    auto box2 = [](const std::string& name, std::vector<double> lo, std::vector<double> hi) {
        return test::box_body(name, lo, hi, std::vector<int> { 2, 1 });
    };
    s["bodies"] = { box2("top", { 0.5, 0.5004 }, { 1.5, 1.0 }), box2("bottom", { 0, 0 }, { 1, 0.5 }) };
    s["contact"] = { { "dhat", 1e-3 }, { "kappa", 1e3 } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", 1 } };
    Eigen::VectorXd dir(3);
    dir << 1, 0, 0;
    check_scene(s, dir, 1 << int(ContactKind::VERTEX_EDGE));

    json t;
    t["dimension"] = 3;
    auto box3 = [](const std::string& name, std::vector<double> lo, std::vector<double> hi, std::vector<int> cells) {
        return test::box_body(name, lo, hi, cells);
    };
    t["bodies"] = { box3("top", { 0.5, 0.5004, 0.5 }, { 1.0, 0.8, 1.0 }, { 1, 1, 1 }),
        box3("bottom", { 0, 0, 0 }, { 1, 0.5, 1 }, { 2, 1, 2 }) };
    t["contact"] = { { "dhat", 1e-3 }, { "kappa", 1e3 } };
    t["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", 1 } };
    Eigen::VectorXd dir3(3);
    dir3 << 0.6, 0, 0.8;
    const auto types = check_scene(t, dir3, 1 << int(ContactKind::VERTEX_FACE));
    // Point-point, point-edge and point-triangle distance types all lagged and differentiated here.
    using PT = PointTriangleDistanceType;
    const int VF = int(ContactKind::VERTEX_FACE);
    auto has = [&](std::initializer_list<PT> any) {
        for (PT t : any)
            if (types.count({ VF, int(t) }))
                return true;
        return false;
    };
    // Vertices exactly above vertices: point-point types next to point-triangle ones.
    EXPECT_TRUE(has({ PT::P_T0, PT::P_T1, PT::P_T2 })) << "no point-point type";
    EXPECT_TRUE(has({ PT::P_T })) << "no point-triangle type";

    // Vertices 0.3 mm beyond the bottom box's top edge (and 0.4 mm above it): their
    // closest feature is the edge's interior (vertex-face point-edge types).
    t["bodies"][0]["mesh"]["box"]["min"] = { 0.5003, 0.5004, 0.25 };
    t["bodies"][0]["mesh"]["box"]["max"] = { 1.0003, 0.8, 0.75 };
    const auto edge_types = check_scene(t, dir3, 1 << int(ContactKind::VERTEX_FACE));
    int point_edge = 0;
    for (PT e : { PT::P_E0, PT::P_E1, PT::P_E2 })
        point_edge += int(edge_types.count({ VF, int(e) }));
    EXPECT_GT(point_edge, 0) << "no vertex-face point-edge type";
}

TEST(FrictionPotential, NearlyParallelEdgesGiveFiniteLaggedData)
{
    // Two boxes whose x-aligned edges are 1e-9 rad from parallel and 0.4 mm apart:
    // the classifier may call such pairs line-line (EA_EB) although a*c - b*b
    // cancels to zero; the lagged data must stay finite (and the FD checks pass).
    json s;
    s["dimension"] = 3;
    auto box = [](const std::string& name, std::vector<double> lo, std::vector<double> hi) {
        return test::box_body(name, lo, hi, std::vector<int> { 1, 1, 1 });
    };
    s["bodies"] = { box("top", { 0.2, 0.5004, 0.5 }, { 0.8, 0.8, 1.1 }), box("bottom", { 0, 0, 0 }, { 1, 0.5, 1 }) };
    s["bodies"][0]["rotation"] = { 0, 1e-9 * 180 / M_PI, 0 };
    s["contact"] = { { "dhat", 1e-3 }, { "kappa", 1e3 } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", 1 } };
    Simulator sim(test::make_scene(s));
    FrictionPotential D(3, std::vector<double>(2, 0.5), sim.mesh().vertex_body, 1e-3);
    D.set_step(sim.positions(), 0.01);
    D.lag(*sim.contact(), sim.positions());
    int line_line = 0;
    for (const Contact& c : sim.contact()->contacts(sim.positions()))
        line_line += c.kind == ContactKind::EDGE_EDGE && c.distance_type == int(EdgeEdgeDistanceType::EA_EB);
    std::printf("  %d line-line edge-edge contacts, %zu lagged\n", line_line, D.lagged().size());
    for (const FrictionContact& f : D.lagged()) {
        EXPECT_TRUE(f.normal.allFinite());
        for (double g : f.weights)
            EXPECT_TRUE(std::isfinite(g));
    }
    VectorXd x = sim.positions();
    x.head(3 * sim.scene().body_vertices / 2) += 1e-6 * test::random_vector(3 * sim.scene().body_vertices / 2, 3);
    VectorXd g = VectorXd::Zero(x.size());
    D.add_gradient(x, 1.0, g);
    EXPECT_TRUE(g.allFinite());

    // The case directly: a*c - b*b is exactly 0 in double for these edges (2e-9 rad apart),
    // |u x v|^2 is not, and the classifier calls the pair line-line.
    VectorXd e(12);
    e << 0, 0, 0, 1, 0, 0, 0, -1e-9, 1e-3, 1, 1e-9, 1e-3;
    Contact c;
    c.kind = ContactKind::EDGE_EDGE;
    c.vertices = { 0, 1, 2, 3 };
    c.distance_type = int(edge_edge_distance_type(e.segment<3>(0), e.segment<3>(3), e.segment<3>(6), e.segment<3>(9)));
    ASSERT_EQ(c.distance_type, int(EdgeEdgeDistanceType::EA_EB));
    const auto w = closest_point_weights(c, e, 3);
    Eigen::Vector3d r = Eigen::Vector3d::Zero();
    for (int i = 0; i < 4; ++i) {
        ASSERT_TRUE(std::isfinite(w[size_t(i)]));
        r += w[size_t(i)] * e.segment<3>(3 * i);
    }
    EXPECT_NEAR(r.norm(), 1e-3, 1e-9);
}
