// Adjoint gradients against central finite differences and Taylor tests, for
// every parameter block, under each integrator, in 2D and 3D, without contact,
// with frictionless contact and with friction. Forward runs converge to residual_tolerance 1e-11
// (relative force residual, docs/math.md), far below what the differences resolve.

#include "adjoint/adjoint_check.hpp"
#include "forward/contact/distance/distance_type.hpp"
#include "tests/forward/periodic/post_cell.hpp"

using namespace diffipc;
using namespace diffipc::test;
using json = nlohmann::json;

namespace {

const std::vector<Block> ALL_BLOCKS = { Block::REST_POSITIONS, Block::MU, Block::LAMBDA, Block::DENSITY,
    Block::INITIAL_DISPLACEMENT, Block::INITIAL_VELOCITY, Block::PRESCRIBED };

/// A soft cantilever under gravity whose clamped end also moves (prescribed values change per step).
json cantilever(int dim, const std::string& integrator, int steps = 3)
{
    json s = dim == 2 ? box_scene(2, { 1.0, 0.2 }, { 4, 2 }, "neo_hookean", 2e4, 0.3, 1000)
                      : box_scene(3, { 1.0, 0.2, 0.2 }, { 3, 1, 1 }, "neo_hookean", 2e4, 0.3, 1000);
    s["gravity"] = dim == 2 ? json { 0, -9.81 } : json { 0, -9.81, 0 };
    s["time"] = { { "integrator", integrator }, { "dt", 0.02 }, { "steps", steps } };
    s["solver"] = { { "residual_tolerance", 1e-11 } };
    const std::vector<double> lo(size_t(dim), -1.0);
    std::vector<double> hi(size_t(dim), 1.0);
    hi[0] = 1e-6;
    json disp = dim == 2 ? json { 0, "0.05*t" } : json { 0, "0.05*t", "0.02*t" };
    s["dirichlet"] = { { { "body", "body" }, { "region", region(lo, hi) }, { "displacement", disp } } };
    s["neumann"] = { { { "body", "body" }, { "region", region({ 0.999, -1, -1 }, { 2, 2, 2 }) },
        { "traction", dim == 2 ? json { 0, "-200*t" } : json { 0, "-200*t", 0 } } } };
    if (dim == 2)
        s["neumann"][0]["region"] = region({ 0.999, -1 }, { 2, 2 });
    if (integrator != "static")
        s["bodies"][0]["initial_velocity"] = dim == 2 ? json { 0.1, 0.2 } : json { 0.1, 0.2, -0.1 };
    return s;
}

} // namespace

class AdjointNoContact : public ::testing::TestWithParam<std::tuple<int, std::string>> { };

TEST_P(AdjointNoContact, EveryBlockMatchesFiniteDifferences)
{
    const auto& [dim, integrator] = GetParam();
    std::vector<Block> blocks = ALL_BLOCKS;
    if (integrator == "static") // no inertia: density enters only through gravity, velocities not at all
        blocks = { Block::REST_POSITIONS, Block::MU, Block::LAMBDA, Block::DENSITY, Block::PRESCRIBED };
    check_adjoint(cantilever(dim, integrator), blocks);
}

INSTANTIATE_TEST_SUITE_P(Integrators, AdjointNoContact,
    ::testing::Combine(::testing::Values(2, 3), ::testing::Values("static", "implicit_euler", "bdf2", "newmark")),
    [](const auto& info) { return std::to_string(std::get<0>(info.param)) + "D_" + std::get<1>(info.param); });

namespace {

/// A soft box resting on a plane obstacle (every bottom vertex within dhat from the
/// start, so the contact set does not change), pressed by gravity while the plane
/// rises (the plane's point is a prescribed dof) and the box slides sideways.
json box_on_plane(int dim, const std::string& integrator)
{
    const double dhat = 2e-3;
    json s = box_over_rising_plane(dim, integrator, dhat, 0.01, 3);
    s["bodies"][0]["translation"] = dim == 2 ? json { 0, 0.5 * dhat } : json { 0, 0.5 * dhat, 0 };
    if (integrator != "static")
        s["bodies"][0]["initial_velocity"] = dim == 2 ? json { 0.1, 0 } : json { 0.1, 0, -0.05 };
    else {
        // Without inertia (and friction) the box needs a hold: its top is clamped while the plane
        // presses from below. A stronger gravity makes J visibly nonlinear in the density (else
        // the Taylor remainder of that block sits at round-off, 1e-13).
        s["gravity"] = dim == 2 ? json { 0, -200 } : json { 0, -200, 0 };
        s["obstacles"][0]["plane"]["motion"] = dim == 2 ? json { 0, "0.02*t" } : json { 0, "0.02*t", 0 };
        const double top = 0.1 + 0.5 * dhat - 1e-6;
        s["dirichlet"] = { { { "body", "body" },
            { "region", dim == 2 ? region({ -1, top }, { 1, 1 }) : region({ -1, top, -1 }, { 1, 1, 1 }) },
            { "displacement", dim == 2 ? json { 0, 0 } : json { 0, 0, 0 } } } };
    }
    return s;
}

/// 3D: a box resting on another, turned by 20 degrees about the vertical so that
/// vertex-face and crossing edge-edge contacts carry the load.
json stacked_boxes(const std::string& integrator)
{
    const double dhat = 2e-3;
    json s = box_scene(3, { 0.2, 0.1, 0.2 }, { 1, 1, 1 }, "neo_hookean", 2e4, 0.3, 1000);
    s["bodies"] = { box_body("below", { 0, 0, 0 }, { 0.2, 0.1, 0.2 }, { 1, 1, 1 }),
        box_body("above", { 0.05, 0.1 + 0.5 * dhat, 0.05 }, { 0.15, 0.15 + 0.5 * dhat, 0.15 }, { 1, 1, 1 }) };
    for (auto& b : s["bodies"])
        b["material"]["E"] = 2e4;
    s["bodies"][1]["rotation"] = { 0, 20, 0 };
    s["gravity"] = { 0, -9.81, 0 };
    s["dirichlet"] = { { { "body", "below" }, { "region", region({ -1, -1, -1 }, { 1, 1e-6, 1 }) },
        { "displacement", { "0.01*t", "0.02*t", 0 } } } };
    s["contact"] = { { "dhat", dhat }, { "kappa", 1e5 } };
    s["time"] = { { "integrator", integrator }, { "dt", 0.01 }, { "steps", 3 } };
    s["solver"] = { { "residual_tolerance", 1e-11 } };
    return s;
}

/// The blocks the box-on-plane scenes check (with or without friction).
std::vector<Block> box_on_plane_blocks(int dim, const std::string& integrator)
{
    if (integrator != "static")
        return ALL_BLOCKS;
    // No inertia: density enters only through gravity, velocities not at all.
    // Written reason: in the 3D static scene every vertex is either clamped (top layer) or
    // held by the barrier (bottom layer, one cell high), so gravity, the density's only
    // effect without inertia, moves J by 1e-10 and no difference quotient resolves it.
    // Density in static solves is checked by the 2D contact case and both no-contact cases.
    if (dim == 3)
        return { Block::REST_POSITIONS, Block::MU, Block::LAMBDA, Block::PRESCRIBED };
    return { Block::REST_POSITIONS, Block::MU, Block::LAMBDA, Block::DENSITY, Block::PRESCRIBED };
}

CheckSettings box_on_plane_settings(const std::string& integrator)
{
    CheckSettings settings;
    settings.tolerance = 1e-5;
    settings.fd_step = 1e-3;
    settings.taylor_step = integrator == "static" ? 0.1 : 1e-2;
    return settings;
}

} // namespace

class AdjointContact : public ::testing::TestWithParam<std::tuple<int, std::string>> { };

TEST_P(AdjointContact, EveryBlockMatchesFiniteDifferences)
{
    const auto& [dim, integrator] = GetParam();
    const json scene = box_on_plane(dim, integrator);
    // The check is only meaningful if the contacts are there all along.
    Simulator sim(make_scene(scene));
    sim.run();
    ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED);
    for (const StepRecord& r : sim.trajectory().steps)
        ASSERT_EQ(r.active_contacts, dim == 2 ? 5 : 9) << "step " << r.index;
    check_adjoint(scene, box_on_plane_blocks(dim, integrator), box_on_plane_settings(integrator));
}

INSTANTIATE_TEST_SUITE_P(Integrators, AdjointContact,
    ::testing::Combine(::testing::Values(2, 3), ::testing::Values("static", "implicit_euler", "bdf2", "newmark")),
    [](const auto& info) { return std::to_string(std::get<0>(info.param)) + "D_" + std::get<1>(info.param); });

TEST(AdjointContact, StackedBoxesVertexFaceAndEdgeEdge)
{
    const json scene = stacked_boxes("implicit_euler");
    Simulator sim(make_scene(scene));
    sim.run();
    ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << sim.trajectory().failure_message;
    int edge_edge = 0, vertex_face = 0;
    for (const Contact& c : sim.trajectory().steps.back().contacts) {
        edge_edge += c.kind == ContactKind::EDGE_EDGE;
        vertex_face += c.kind == ContactKind::VERTEX_FACE;
    }
    ASSERT_GT(edge_edge, 0);
    ASSERT_GT(vertex_face, 0);
    CheckSettings settings;
    settings.tolerance = 1e-5;
    check_adjoint(scene, ALL_BLOCKS, settings);
}

namespace {

/// box_on_plane with friction: the plane also moves sideways under the box, which
/// slides over it (dynamic: faster than the plane; static: dragged against the hold).
json box_on_plane_with_friction(int dim, const std::string& integrator)
{
    json s = box_on_plane(dim, integrator);
    // Unequal sides: the pair's coefficient sqrt(0.2 * 0.45) = 0.3 has different
    // derivatives with respect to each group's coefficient.
    s["friction"] = { { "coefficient", 0.3 }, { "eps_v", 1e-3 } };
    s["bodies"][0]["friction"] = { { "coefficient", 0.2 } };
    s["obstacles"][0]["friction"] = { { "coefficient", 0.45 } };
    const std::string rise = integrator == "static" ? "0.02*t" : "0.01*t";
    s["obstacles"][0]["plane"]["motion"] = dim == 2 ? json { "0.05*t", rise } : json { "0.05*t", rise, "0.02*t" };
    if (integrator != "static")
        s["bodies"][0]["initial_velocity"] = dim == 2 ? json { 0.2, 0 } : json { 0.2, 0, -0.1 };
    return s;
}

} // namespace

class AdjointFriction : public ::testing::TestWithParam<std::tuple<int, std::string>> { };

TEST_P(AdjointFriction, EveryBlockMatchesFiniteDifferences)
{
    const auto& [dim, integrator] = GetParam();
    const json scene = box_on_plane_with_friction(dim, integrator);
    // Meaningful only if every bottom vertex carries friction at every step.
    Simulator sim(make_scene(scene));
    sim.run();
    ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << sim.trajectory().failure_message;
    for (const StepRecord& r : sim.trajectory().steps) {
        ASSERT_EQ(r.active_contacts, dim == 2 ? 5 : 9) << "step " << r.index;
        ASSERT_EQ(r.friction.size(), size_t(r.active_contacts)) << "step " << r.index;
    }
    std::vector<Block> blocks = box_on_plane_blocks(dim, integrator);
    blocks.push_back(Block::FRICTION);
    check_adjoint(scene, blocks, box_on_plane_settings(integrator));
}

INSTANTIATE_TEST_SUITE_P(Integrators, AdjointFriction,
    ::testing::Combine(::testing::Values(2, 3), ::testing::Values("static", "implicit_euler", "bdf2", "newmark")),
    [](const auto& info) { return std::to_string(std::get<0>(info.param)) + "D_" + std::get<1>(info.param); });

TEST(AdjointFriction, StackedBoxesVertexFaceAndEdgeEdge)
{
    json scene = stacked_boxes("implicit_euler");
    scene["friction"] = { { "coefficient", 0.3 }, { "eps_v", 1e-3 } };
    scene["bodies"][1]["initial_velocity"] = { 0.1, 0, 0.05 };
    Simulator sim(make_scene(scene));
    sim.run();
    ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << sim.trajectory().failure_message;
    int edge_edge = 0, vertex_face = 0;
    for (const FrictionContact& f : sim.trajectory().steps.back().friction) {
        edge_edge += f.kind == ContactKind::EDGE_EDGE;
        vertex_face += f.kind == ContactKind::VERTEX_FACE;
    }
    ASSERT_GT(edge_edge, 0);
    ASSERT_GT(vertex_face, 0);
    std::vector<Block> blocks = ALL_BLOCKS;
    blocks.push_back(Block::FRICTION);
    CheckSettings settings;
    settings.tolerance = 1e-5;
    check_adjoint(scene, blocks, settings);
}

TEST(AdjointFriction, StackedBoxes2DVertexEdge)
{
    // A 2D box sliding over another one, offset so that every contact is a vertex
    // inside the other box's edge (closest-point weights and normals vary with x_{k-1}).
    const double dhat = 2e-3;
    json s = box_scene(2, { 0.2, 0.1 }, { 2, 1 }, "neo_hookean", 2e4, 0.3, 1000);
    s["bodies"] = { box_body("below", { 0, 0 }, { 0.2, 0.1 }, { 2, 1 }),
        box_body("above", { 0.03, 0.1 + 0.5 * dhat }, { 0.13, 0.15 + 0.5 * dhat }, { 2, 1 }) };
    for (auto& b : s["bodies"])
        b["material"]["E"] = 2e4;
    s["bodies"][1]["initial_velocity"] = { 0.1, 0 };
    s["gravity"] = { 0, -9.81 };
    s["dirichlet"] = { { { "body", "below" }, { "region", region({ -1, -1 }, { 1, 1e-6 }) },
        { "displacement", { "0.01*t", "0.02*t" } } } };
    s["contact"] = { { "dhat", dhat }, { "kappa", 1e8 } };
    s["friction"] = { { "coefficient", 0.3 }, { "eps_v", 1e-3 } };
    s["time"] = { { "integrator", "bdf2" }, { "dt", 0.01 }, { "steps", 3 } };
    s["solver"] = { { "residual_tolerance", 1e-11 } };
    Simulator sim(make_scene(s));
    sim.run();
    ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << sim.trajectory().failure_message;
    for (const StepRecord& r : sim.trajectory().steps) {
        int interior = 0;
        for (const FrictionContact& f : r.friction)
            interior += f.kind == ContactKind::VERTEX_EDGE
                && PointEdgeDistanceType(f.source.distance_type) == PointEdgeDistanceType::P_E;
        ASSERT_EQ(interior, 4) << "step " << r.index;
        EXPECT_GT(r.min_distance, 0.05 * dhat) << "step " << r.index;
    }
    std::vector<Block> blocks = ALL_BLOCKS;
    blocks.push_back(Block::FRICTION);
    CheckSettings settings;
    settings.tolerance = 1e-5;
    check_adjoint(s, blocks, settings);
}

TEST(AdjointFriction, StickingBoxOnAcceleratingPlane)
{
    // The plane accelerates sideways at 1 m/s^2 under a box with mu = 0.8: friction
    // carries the box (the smoothed law's sticking branch, |t| < eps = eps_v h, at every
    // contact and step; checked below from the velocities).
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE(dim);
        json s = box_on_plane(dim, "implicit_euler");
        s["friction"] = { { "coefficient", 0.8 }, { "eps_v", 1e-3 } };
        s["obstacles"][0]["plane"]["motion"]
            = dim == 2 ? json { "0.5*t*t", "0.01*t" } : json { "0.5*t*t", "0.01*t", "0.25*t*t" };
        s["bodies"][0].erase("initial_velocity");
        s["bodies"][0]["material"]["E"] = 1e6; // stiff enough that its bottom moves as one
        // A barrier that carries the box's weight at its starting height (0.5 dhat): the normal
        // forces lagged at x_0 are then the resting ones, not those of a box still settling.
        s["contact"]["kappa"] = dim == 2 ? 1.2e9 : 1.2e8;
        // The lambda block's derivative is tiny (3.5e-5 in 3D against 1e-2 for the others), so the
        // forward runs' convergence noise shows in its difference: at residual 1e-11 it was
        // 5.7e-7 relative, or 3e-5 where the step extension changed the perturbed runs' Newton
        // paths; at 1e-13 it is at most 4.1e-6 either way.
        s["solver"]["residual_tolerance"] = 1e-13;
        Simulator sim(make_scene(s));
        sim.run();
        ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << sim.trajectory().failure_message;
        const double eps_v = 1e-3;
        for (const StepRecord& r : sim.trajectory().steps) {
            ASSERT_EQ(r.friction.size(), size_t(dim == 2 ? 5 : 9)) << "step " << r.index;
            // Each bottom vertex's velocity against the plane point's (both (x_k - x_{k-1}) / h):
            // their tangential difference is the slip rate, below eps_v when sticking.
            for (const FrictionContact& f : r.friction) {
                const Index v = f.vertices[0], plane = f.vertices[1];
                const double slip_x = r.velocities[v * dim] - r.velocities[plane * dim];
                const double slip_z = dim == 3 ? r.velocities[v * dim + 2] - r.velocities[plane * dim + 2] : 0.0;
                EXPECT_LT(std::hypot(slip_x, slip_z), eps_v) << "step " << r.index << " vertex " << v;
            }
        }
        std::vector<Block> blocks = box_on_plane_blocks(dim, "implicit_euler");
        blocks.push_back(Block::FRICTION);
        // Written reason for the smaller difference step: f0 is only C2 where the sticking
        // branch meets the sliding one (|t| = eps = 1e-5 m here), and the fourth-order
        // difference needs J smooth over +-2 steps. With the default step an initial
        // displacement moves tangential displacements by ~4e-6 m and crosses |t| = eps
        // (observed error 2e-4 while the Taylor rate stays 2); 2e-5 keeps them within 2% of eps.
        // The friction block's derivative is small (3e-6 in 2D), so a step much smaller lets the
        // forward runs' round-off show: with the element kernels of forward/kernels/, measured at
        // steps 3e-6, 5e-6, 1e-5, 2e-5, 4e-5, its error was 9.8e-6, 2.0e-5, 2.0e-5, 4.7e-7, 1.1e-7
        // in 2D (not shrinking with the tolerance 1e-14 either: round-off, not convergence), and at
        // 2e-5 every block's error is at most 4.8e-7.
        CheckSettings settings = box_on_plane_settings("implicit_euler");
        settings.fd_step = 2e-5;
        check_adjoint(s, blocks, settings);
    }
}

TEST(AdjointFriction, ZeroCoefficientInContactIsRefusedOnlyWhenRequested)
{
    // The plane has mu = 0, the box mu = 0.3: the pair has no friction, and
    // d sqrt(mu_box mu_plane)/d mu_plane is unbounded at 0.
    json s = box_on_plane(2, "implicit_euler");
    s["friction"] = { { "coefficient", 0.3 } };
    s["obstacles"][0]["friction"] = { { "coefficient", 0.0 } };
    s["bodies"] = { s["bodies"][0], box_body("free", { 1, 1 }, { 1.1, 1.1 }, { 1, 1 }) };
    SimulationParameters nominal;
    Simulator sim(make_scene(s), nominal);
    sim.run();
    ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << sim.trajectory().failure_message;
    ASSERT_NE(sim.friction(), nullptr); // the free body's coefficient keeps a potential
    const StateObjective objective(sim.steps_done(), sim.mesh().num_dofs(), sim.bbox_diagonal(), 0.01, 3);
    ParameterRequest request;
    request.rest_positions = true;
    EXPECT_NO_THROW(adjoint_gradient(sim, objective.seed(sim), request));
    request.friction = true;
    EXPECT_THROW(adjoint_gradient(sim, objective.seed(sim), request), AdjointError);
}

TEST(AdjointPenalty, PenaltyContactIsRefusedWithAMessage)
{
    // The penalty baseline (contact.model "penalty") is a forward option; the adjoint says so.
    json s = box_on_plane(2, "implicit_euler");
    s["contact"] = { { "dhat", 1e-3 }, { "model", "penalty" }, { "penalty_stiffness", 1e6 } };
    Simulator sim(make_scene(s));
    sim.run();
    ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << sim.trajectory().failure_message;
    const StateObjective objective(sim.steps_done(), sim.mesh().num_dofs(), sim.bbox_diagonal(), 0.01, 3);
    ParameterRequest request;
    request.rest_positions = true;
    try {
        adjoint_gradient(sim, objective.seed(sim), request);
        ADD_FAILURE() << "no AdjointError";
    } catch (const AdjointError& e) {
        EXPECT_NE(std::string(e.what()).find("penalty"), std::string::npos) << e.what();
    }
}

TEST(AdjointGradients, SharedFactorizationsGiveEachSeedsGradient)
{
    // Several objectives swept together over one run (one factorization per step) must give
    // what separate sweeps give, for every integrator's history and with friction's terms.
    for (const std::string integrator : { "static", "implicit_euler", "bdf2", "newmark" }) {
        SCOPED_TRACE(integrator);
        json s = box_on_plane(2, integrator);
        if (integrator == "implicit_euler")
            s["friction"] = { { "coefficient", 0.3 } };
        Simulator sim(make_scene(s));
        sim.run();
        ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << sim.trajectory().failure_message;
        const Index n = sim.mesh().num_dofs();
        std::vector<StateSeed> seeds;
        for (unsigned seed : { 3u, 5u, 9u })
            seeds.push_back(StateObjective(sim.steps_done(), n, sim.bbox_diagonal(), 0.01, seed).seed(sim));
        seeds[1].positions[0] = VectorXd(); // a seed that leaves a state empty
        ParameterRequest request;
        request.rest_positions = request.lame = request.density = request.prescribed = true;
        request.initial_velocity = integrator != "static";
        request.friction = integrator == "implicit_euler";
        AdjointStatistics shared;
        const std::vector<ParameterGradient> together = adjoint_gradients(sim, seeds, request, &shared);
        ASSERT_EQ(together.size(), seeds.size());
        for (size_t i = 0; i < seeds.size(); ++i) {
            const ParameterGradient alone = adjoint_gradient(sim, seeds[i], request);
            const auto same = [&](const VectorXd& a, const VectorXd& b, const char* name) {
                ASSERT_EQ(a.size(), b.size()) << name;
                EXPECT_LE((a - b).norm(), 1e-12 * b.norm()) << name << " of seed " << i;
            };
            same(together[i].rest_positions, alone.rest_positions, "rest_positions");
            same(together[i].mu, alone.mu, "mu");
            same(together[i].lambda, alone.lambda, "lambda");
            same(together[i].density, alone.density, "density");
            same(together[i].initial_velocity, alone.initial_velocity, "initial_velocity");
            same(together[i].friction, alone.friction, "friction");
            EXPECT_LE((together[i].prescribed - alone.prescribed).norm(), 1e-12 * alone.prescribed.norm());
        }
        EXPECT_EQ(shared.steps, 3 * sim.steps_done()) << "one solve per seed and step";
    }
}

TEST(AdjointGradients, SweepsThatReachTheirFirstSolveAtDifferentSteps)
{
    // Seeds on different states: at the last steps the first sweep has nothing to solve and a
    // later one factorizes the shared system; the first then solves at an earlier step. Each
    // gradient must be its own sweep's.
    for (const std::string integrator : { "static", "implicit_euler" }) {
        SCOPED_TRACE(integrator);
        Simulator sim(make_scene(box_on_plane(2, integrator)));
        sim.run();
        ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED);
        const int T = sim.steps_done();
        ASSERT_GE(T, 3);
        const Index n = sim.mesh().num_dofs();
        std::vector<StateSeed> seeds(3);
        for (int i = 0; i < 3; ++i) {
            seeds[size_t(i)].resize(T);
            const int k = i == 0 ? 1 : i == 1 ? T : T - 1; // state 1 first, then T, then T - 1
            seeds[size_t(i)].add_position(k, random_vector(n, unsigned(40 + i)) / sim.bbox_diagonal());
        }
        ParameterRequest request;
        request.rest_positions = request.lame = request.prescribed = true;
        const std::vector<ParameterGradient> together = adjoint_gradients(sim, seeds, request);
        for (size_t i = 0; i < seeds.size(); ++i) {
            const ParameterGradient alone = adjoint_gradient(sim, seeds[i], request);
            ASSERT_GT(alone.mu.norm(), 0) << "seed " << i << ": an empty check";
            EXPECT_LE((together[i].rest_positions - alone.rest_positions).norm(), 1e-12 * alone.rest_positions.norm())
                << "seed " << i;
            EXPECT_LE((together[i].mu - alone.mu).norm(), 1e-12 * alone.mu.norm()) << "seed " << i;
            EXPECT_LE((together[i].lambda - alone.lambda).norm(), 1e-12 * alone.lambda.norm()) << "seed " << i;
            EXPECT_LE((together[i].prescribed - alone.prescribed).norm(), 1e-12 * alone.prescribed.norm())
                << "seed " << i;
        }
    }
}

TEST(AdjointLoadStepping, GradientsThroughSubsteppedStaticStepsMatchFiniteDifferences)
{
    // A neo-Hookean block compressed by 60% in 2 static steps of at most 4 Newton iterations:
    // each step is solved in sub-steps of its load increment (time.adaptive). Its state is the
    // equilibrium at the step's time, so the adjoint of the step is unchanged; every forward run
    // of the finite differences sub-steps on its own.
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE(dim);
        json s = dim == 2 ? box_scene(2, { 1, 1 }, { 4, 4 }, "neo_hookean", 1e5, 0.3, 1000)
                          : box_scene(3, { 1, 1, 1 }, { 2, 2, 2 }, "neo_hookean", 1e5, 0.3, 1000);
        const json zero = dim == 2 ? json { 0, 0 } : json { 0, 0, 0 };
        json down = zero;
        down[1] = "-0.6*t";
        std::vector<double> lo(size_t(dim), -1), hi(size_t(dim), 2), top(size_t(dim), -1);
        hi[1] = 1e-6;
        top[1] = 1 - 1e-6;
        s["dirichlet"] = { { { "body", 0 }, { "region", region(lo, hi) }, { "displacement", zero } },
            { { "body", 0 }, { "region", region(top, std::vector<double>(size_t(dim), 2)) },
                { "displacement", down } } };
        s["gravity"] = dim == 2 ? json { 0, -20 } : json { 0, -20, 0 };
        s["time"] = { { "integrator", "static" }, { "dt", 0.5 }, { "steps", 2 }, { "adaptive", true } };
        s["solver"] = { { "residual_tolerance", 1e-11 }, { "max_iterations", 4 } };
        Simulator sim(make_scene(s));
        sim.run();
        ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << sim.trajectory().failure_message;
        ASSERT_GT(sim.trajectory().totals.substepped_steps, 0) << "no step was sub-stepped: the check would be plain";
        check_adjoint(s, { Block::REST_POSITIONS, Block::MU, Block::LAMBDA, Block::DENSITY, Block::PRESCRIBED });
    }
}

TEST(AdjointLoadStepping, GradientsThroughSubsteppedDynamicStepsMatchFiniteDifferences)
{
    // The box on the rising plane, its dynamic steps taken in sub-steps, each a step of the
    // integrator from the last sub-step's state; the adjoint sweeps back through them. The
    // differentiated run is the path the run took: check_adjoint's forward runs are built from
    // sim.parameters(), which hold its sub-steps (SimulationParameters::substeps).
    // Given sub-steps of unequal lengths (0.3, 0.5 and 0.2 of each step), both integrators:
    for (int dim : { 2, 3 })
        for (const char* integrator : { "implicit_euler", "newmark" }) {
            SCOPED_TRACE(std::to_string(dim) + "D " + integrator + ", given sub-steps");
            const json s = box_on_plane(dim, integrator);
            std::vector<std::vector<double>> substeps;
            for (int k = 1; k <= 3; ++k)
                substeps.push_back({ 0.01 * (k - 1) + 0.003, 0.01 * (k - 1) + 0.008, 0.01 * k });
            check_adjoint(s, ALL_BLOCKS, box_on_plane_settings(integrator), 0, substeps);
        }
    // Sub-steps chosen by time.adaptive: the box falls onto the plane (rising at 0.2 m/s); with at
    // most 9 Newton iterations per solve its landing step fails as one and is split.
    for (int dim : { 2, 3 }) {
        SCOPED_TRACE(std::to_string(dim) + "D implicit_euler, time.adaptive");
        json s = box_over_rising_plane(dim, "implicit_euler", 2e-3, 0.04, 2);
        s["bodies"][0]["translation"] = dim == 2 ? json { 0, 0.01 } : json { 0, 0.01, 0 };
        s["bodies"][0]["initial_velocity"] = dim == 2 ? json { 0.1, -0.5 } : json { 0.1, -0.5, -0.05 };
        s["obstacles"][0]["plane"]["motion"] = dim == 2 ? json { 0, "0.2*t" } : json { 0, "0.2*t", 0 };
        s["contact"]["kappa"] = 1e7;
        s["time"]["adaptive"] = { { "min_increment", 0.04 / 64 } };
        s["solver"]["max_iterations"] = 9;
        Simulator sim(make_scene(s));
        sim.run();
        ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << sim.trajectory().failure_message;
        ASSERT_GT(sim.trajectory().totals.substepped_steps, 0) << "no step was sub-stepped: the check would be plain";
        ASSERT_GT(sim.trajectory().step(2).active_contacts, 0) << "the box does not land";
        // The finite differences repeat the sub-steps taken (the run's parameters()). Their
        // perturbed solves may need a few more iterations than the 9 that made the steps fail.
        s["solver"]["max_iterations"] = 100;
        check_adjoint(s, ALL_BLOCKS, box_on_plane_settings("implicit_euler"), 0, sim.parameters().substeps);
    }
}

TEST(AdjointLoadStepping, SubsteppedStepsWithFrictionAreRefusedNamingTheStep)
{
    // With friction a sub-stepped step's state slid from its last sub-step's start, not from the
    // previous step's state that the adjoint differentiates: no gradient, and a message saying so.
    json s = box_scene(2, { 1, 1 }, { 4, 4 }, "neo_hookean", 1e5, 0.3, 1000);
    s["dirichlet"] = { { { "body", 0 }, { "region", region({ -1, 1 - 1e-6 }, { 2, 2 }) },
        { "displacement", { "0.3*t", "-0.6*t" } } } };
    s["obstacles"] = { { { "name", "floor" }, { "plane", { { "point", { 0, -0.002 } }, { "normal", { 0, 1 } } } } } };
    s["contact"] = { { "dhat", 0.01 }, { "kappa", 1e5 } };
    s["friction"] = { { "coefficient", 0.3 }, { "eps_v", 1e-3 } };
    s["time"] = { { "integrator", "static" }, { "dt", 0.5 }, { "steps", 2 }, { "adaptive", true } };
    s["solver"] = { { "residual_tolerance", 1e-10 }, { "max_iterations", 8 } };
    Simulator sim(make_scene(s));
    sim.run();
    ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << sim.trajectory().failure_message;
    ASSERT_GT(sim.trajectory().step(1).substeps, 0);
    const StateObjective objective(sim.steps_done(), sim.mesh().num_dofs(), sim.bbox_diagonal(), 0.01, 3);
    ParameterRequest request;
    request.rest_positions = true;
    try {
        adjoint_gradient(sim, objective.seed(sim), request);
        FAIL() << "no error";
    } catch (const AdjointError& e) {
        EXPECT_NE(std::string(e.what()).find("step 1 was solved in sub-steps with friction"), std::string::npos)
            << e.what();
    }
}

TEST(AdjointLoadStepping, GradientsThroughASnapPassedByControlOrRelaxationMatchFiniteDifferences)
{
    // The shallow arch snaps through in step 3; with 8 Newton iterations per solve, the step
    // passes the limit point by displacement control, or (without it) by proximal relaxation,
    // and ends with a plain solve at t_3 (forward/simulation/load_stepping.cpp). That state is the
    // equilibrium at t_3 on the snapped branch, so the step's adjoint is the usual one; every
    // forward run of the differences takes its own path.
    for (bool control : { true, false }) {
        SCOPED_TRACE(control ? "displacement control" : "relaxation");
        json s = shallow_arch(3, 8, { { "displacement_control", control } });
        // Near the snap the arch has a soft mode: a state converged to a residual r is off along
        // it by r / its stiffness, and the differences see that. At 1e-11 it showed as 1.3-2e-6
        // relative error (how much depends on each perturbed run's Newton path: 4e-7 without the
        // step extension); at 3e-12 the error is 2e-7 either way, the differences' truncation.
        s["solver"]["residual_tolerance"] = 3e-12;
        Simulator sim(make_scene(s));
        sim.run();
        ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << sim.trajectory().failure_message;
        const StepRecord& snap = sim.trajectory().step(3);
        ASSERT_GT(control ? snap.control_steps : snap.relaxation_steps, 0) << "the check would be plain";
        CheckSettings settings;
        // Rest positions move by at most 1e-6 of the diagonal in the differences and 1e-4 in the
        // Taylor test: the snapped arch is so nonlinear in its shape and its Lame parameters that
        // the fourth-order difference's truncation error is 2.5e-5 at 1e-3, 2e-3 at 3e-3 (shape).
        // With the element kernels of forward/kernels/ the lambda block's was measured at 1.1e-5 at
        // 3e-4 (2.0e-6 converged to 3e-13: a truncation, 15 times smaller at 1.5e-4), and every
        // block's error at 1e-4 was at most 3.3e-7 (at 3e-12 and at 3e-13).
        settings.fd_step = 1e-4;
        settings.taylor_step = 0.01;
        check_adjoint(s, { Block::REST_POSITIONS, Block::MU, Block::LAMBDA }, settings, 1e5);
    }
}

TEST(AdjointPeriodic, ShapeMaterialDensityVelocityAndMacroGradientsOfAPeriodicCellMatchFiniteDifferences)
{
    // A periodic cell compressed by G_xx = -0.2 t with its lateral component free (scene
    // "periodic"): the adjoint sweeps the cell's reduced unknowns (P^T H P lambda_q = P^T dJ/dx,
    // lambda = P lambda_q); the shape block moves the rest positions keeping the pairing (at fixed
    // q, x = X + G (X - X_o) + w moves with X: docs/math.md); the macro block is dJ/dG of G's prescribed components per
    // step (SimulationParameters::macro_gradient; the direction also moves the free components' entries, which the
    // forward ignores). The random per-element perturbations of the Lame parameters make the cell heterogeneous, so the
    // fluctuation and the free component respond. Static and implicit Euler, 2D and 3D.
    for (int dim : { 2, 3 })
        for (const char* integrator : { "static", "implicit_euler" }) {
            SCOPED_TRACE(std::to_string(dim) + "D " + integrator);
            json s = compressed_periodic_cell(dim, integrator);
            std::vector<Block> blocks { Block::REST_POSITIONS, Block::MU, Block::LAMBDA, Block::DENSITY, Block::MACRO };
            if (std::string(integrator) != "static") {
                s["bodies"][0]["initial_velocity"] = dim == 2 ? json { 0.1, -0.05 } : json { 0.1, -0.05, 0.02 };
                blocks.push_back(Block::INITIAL_VELOCITY);
            }
            check_adjoint(s, blocks);
        }
}

namespace {

/// The post cell (tests/forward/periodic/post_cell.hpp) for the adjoint checks, its mesh written
/// to a file of this process: fixed kappa 1e7, forward residual 1e-11, `edit` applied; run once
/// to check that it converges and that `engaged` holds of its trajectory (else the check would
/// not see the contact). Returns the scene and the mesh file (remove it after the check).
std::pair<json, std::string> post_cell_for_adjoint(int dim, const char* integrator, double strain, int steps,
    const std::function<void(json&)>& edit, const std::function<bool(const Trajectory&)>& engaged)
{
    const std::string path = "/tmp/diffipc_adjoint_post_cell_" + std::to_string(::getpid()) + ".msh";
    json s = post_cell_scene(dim, path, strain, steps, 1e7);
    s["time"]["integrator"] = integrator;
    s["solver"]["residual_tolerance"] = 1e-11;
    edit(s);
    Simulator sim(make_scene(s));
    sim.run();
    EXPECT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << sim.trajectory().failure_message;
    EXPECT_TRUE(engaged(sim.trajectory())) << "the posts do not engage";
    return { s, path };
}

} // namespace

TEST(AdjointPeriodic, GradientsWithContactAcrossTheCellBoundaryMatchFiniteDifferences)
{
    // The post cell (tests/forward/periodic/post_cell.hpp) compressed to G_yy = -0.12 in two
    // steps: at the second its posts press on the next cell's across the boundary (the gap
    // closes at -0.1), so the adjoint's Hessian carries the barrier through the periodic images
    // (T^T H_s T, reduced by P). Fixed kappa; 2D static and 3D implicit Euler (the homogenized
    // stress's test, tests/objectives/test_macro_stress.cpp, runs all four).
    for (const auto& [dim, integrator] : { std::pair { 2, "static" }, std::pair { 3, "implicit_euler" } }) {
        SCOPED_TRACE(std::to_string(dim) + "D " + integrator);
        const auto [s, path] = post_cell_for_adjoint(
            dim, integrator, -0.12, 2, [](json&) {},
            [](const Trajectory& tr) { return tr.committed() == 2 && tr.step(2).active_contacts > 0; });
        // Density is left to the test above: with dt = 0.5 s its effect is below what the
        // Taylor test resolves.
        const std::vector<Block> blocks { Block::REST_POSITIONS, Block::MU, Block::LAMBDA, Block::MACRO };
        CheckSettings settings;
        settings.tolerance = 1e-5;
        settings.fd_step = 2.5e-4; // the barrier's derivatives near contact (CheckSettings::fd_step)
        // Frictionless sliding of the posts' faces is smooth until a vertex passes one of the
        // other face (a change of distance type, where the barrier's Hessian jumps): the
        // grids are offset by about 0.007 m there, which a macro shear of 0.012 (h = 0.1)
        // exceeds. Steps from 0.01 keep the sliding below it.
        settings.taylor_step = 0.01;
        check_adjoint(s, blocks, settings, 1e7);
        std::remove(path.c_str());
    }
}

TEST(AdjointPeriodic, GradientsWithFrictionAcrossTheCellBoundaryMatchFiniteDifferences)
{
    // The post cell pressed to G_yy = -0.18 in three steps and sheared by G_xy = 0.002 t, so that
    // its posts, in contact from the second step on, slide a little on the next cell's under
    // friction in the third (mu 0.3, lagged once per step at its start, through the periodic
    // images like the barrier). Every block a periodic cell has, the friction coefficient's included.
    for (const auto& [dim, integrator] : { std::pair { 2, "static" }, std::pair { 3, "static" } }) {
        SCOPED_TRACE(std::to_string(dim) + "D " + integrator);
        const auto [s, path] = post_cell_for_adjoint(
            dim, integrator, -0.18, 3,
            [](json& scene) {
                scene["periodic"]["gradient"][0][1] = "0.002*t";
                scene["friction"] = { { "coefficient", 0.3 } };
            },
            [](const Trajectory& tr) { return tr.committed() == 3 && !tr.step(3).friction.empty(); });
        CheckSettings settings;
        settings.tolerance = 1e-5;
        settings.fd_step = 2.5e-4;
        // The macro block's Taylor steps as above (the sliding faces' vertices must not pass each
        // other); the others from 0.1, where the remainders stand above the lagged forward
        // solves' noise (about 1e-7 of this J).
        settings.taylor_step = 0.01;
        check_adjoint(s, { Block::MACRO }, settings, 1e7);
        settings.taylor_step = 0.1;
        check_adjoint(s, { Block::REST_POSITIONS, Block::MU, Block::LAMBDA, Block::FRICTION }, settings, 1e7);
        std::remove(path.c_str());
    }
}

TEST(AdjointPeriodic, PrescribedAndInitialDisplacementGradientsOfPeriodicCellsAreRefusedNamingWhat)
{
    json s = box_scene(2, { 1, 0.8 }, { 3, 2 }, "neo_hookean", 1e5, 0.3, 1000);
    s["periodic"] = { { "gradient", { { "-0.1*t", 0 }, { 0, nullptr } } } };
    s["time"] = { { "integrator", "static" }, { "dt", 1.0 }, { "steps", 1 } };
    Simulator sim(make_scene(s));
    sim.run();
    ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << sim.trajectory().failure_message;
    const StateObjective objective(1, sim.mesh().num_dofs(), sim.bbox_diagonal(), 1.0, 3);
    for (int which = 0; which < 2; ++which) {
        ParameterRequest request;
        (which == 0 ? request.prescribed : request.initial_displacement) = true;
        try {
            adjoint_gradient(sim, objective.seed(sim), request);
            ADD_FAILURE() << "no error";
        } catch (const AdjointError& e) {
            EXPECT_NE(std::string(e.what()).find("a periodic cell has no prescribed-value or initial-displacement"),
                std::string::npos)
                << e.what();
        }
    }
}
