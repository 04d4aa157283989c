// Checkpointed adjoint gradients (adjoint/checkpointing.hpp) against the
// full-memory adjoint_gradient(), under each integrator, in 2D and 3D, without
// and with (frictionless) contact: the same gradient to round-off while fewer
// records than steps hold their state.

#include "adjoint/adjoint_check.hpp"
#include "adjoint/checkpointing.hpp"

#include <algorithm>
#include <cstdio>
#include <ostream>

using namespace diffipc;
using namespace diffipc::test;
using json = nlohmann::json;

namespace {

constexpr int STEPS = 14;

/// A bar clamped at x = 0 whose clamp moves in time, under gravity and a growing tip traction.
json moving_bar(int dim, const std::string& integrator)
{
    json s = dim == 2 ? box_scene(2, { 0.5, 0.1 }, { 5, 2 }, "neo_hookean", 1e6, 0.3, 1000)
                      : box_scene(3, { 0.5, 0.1, 0.1 }, { 4, 1, 1 }, "neo_hookean", 1e6, 0.3, 1000);
    s["gravity"] = dim == 2 ? json { 0, -9.81 } : json { 0, -9.81, 0 };
    s["time"] = { { "integrator", integrator }, { "dt", 0.01 }, { "steps", STEPS } };
    s["solver"] = { { "residual_tolerance", 1e-11 } };
    std::vector<double> lo(size_t(dim), -1.0), hi(size_t(dim), 1.0);
    hi[0] = 1e-6;
    s["dirichlet"] = { { { "body", "body" }, { "region", region(lo, hi) },
        { "displacement", dim == 2 ? json { "0.02*t", "0.01*sin(30*t)" } : json { "0.02*t", "0.01*sin(30*t)", 0 } } } };
    lo.assign(size_t(dim), -1.0);
    hi.assign(size_t(dim), 2.0);
    lo[0] = 0.5 - 1e-6;
    s["neumann"] = { { { "body", "body" }, { "region", region(lo, hi) },
        { "traction", dim == 2 ? json { 0, "-2000*t" } : json { 0, "-2000*t", "500*t" } } } };
    if (integrator != "static")
        s["bodies"][0]["initial_velocity"] = dim == 2 ? json { 0.05, 0.2 } : json { 0.05, 0.2, -0.1 };
    return s;
}

/// A soft box that falls onto a rising plane and lands during the run (dynamic), or
/// whose clamped top presses it onto the plane (static): contacts appear and change.
json landing_box(int dim, const std::string& integrator)
{
    const double dhat = 2e-3;
    json s = box_over_rising_plane(dim, integrator, dhat, 0.005, STEPS);
    if (integrator != "static") {
        s["bodies"][0]["translation"] = dim == 2 ? json { 0, 2.5 * dhat } : json { 0, 2.5 * dhat, 0 };
        s["bodies"][0]["initial_velocity"] = dim == 2 ? json { 0.1, -0.3 } : json { 0.1, -0.3, 0.05 };
    } else {
        s["bodies"][0]["translation"] = dim == 2 ? json { 0, 0.8 * dhat } : json { 0, 0.8 * dhat, 0 };
        const double top = 0.1 + 0.8 * dhat - 1e-6;
        s["dirichlet"] = { { { "body", "body" },
            { "region", dim == 2 ? region({ -1, top }, { 1, 1 }) : region({ -1, top, -1 }, { 1, 1, 1 }) },
            { "displacement", dim == 2 ? json { "0.2*t", "-0.04*t" } : json { "0.2*t", "-0.04*t", "0.1*t" } } } };
    }
    return s;
}

/// StateObjective (adjoint_check.hpp) shown state by state: its value summed in
/// the forward, its seed given per segment.
struct StreamedStateObjective {
    const StateObjective& objective;
    double value = 0;
    std::vector<std::pair<int, int>> segments; ///< (first, last) of each seed() call

    StreamedObjective callbacks()
    {
        StreamedObjective o;
        o.observe = [this](const Simulator& sim, int k) {
            const Trajectory& tr = sim.trajectory();
            const VectorXd X = flatten(sim.mesh().rest_positions);
            const VectorXd& x = StateObjective::x(tr, k);
            value += objective.a[size_t(k)].dot(x - X) + objective.b[size_t(k)].dot(StateObjective::v(tr, k));
            if (k == sim.scene().time.steps)
                value += 0.5 * objective.c * (x - X).squaredNorm();
        };
        o.seed = [this](const Simulator& sim, int first, int last, StateSeed& seed) {
            segments.emplace_back(first, last);
            for (int k = first; k <= last; ++k) {
                seed.add_position(k, objective.a[size_t(k)]);
                seed.add_velocity(k, objective.b[size_t(k)]);
            }
            const int T = sim.scene().time.steps;
            if (last != T)
                return;
            const VectorXd u = StateObjective::x(sim.trajectory(), T) - flatten(sim.mesh().rest_positions);
            seed.add_position(T, objective.c * u);
            VectorXd sum_a = VectorXd::Zero(u.size());
            for (const VectorXd& a : objective.a)
                sum_a += a;
            seed.explicit_partials.rest_positions = -objective.c * u - sum_a;
        };
        return o;
    }
};

double relative_difference(const VectorXd& a, const VectorXd& b) { return (a - b).norm() / b.norm(); }

struct Case {
    int dim;
    std::string integrator;
    bool contact;
    int stride; ///< 0: the default
};

void PrintTo(const Case& c, std::ostream* os)
{
    *os << c.dim << "D " << c.integrator << (c.contact ? " contact" : " free") << " stride " << c.stride;
}

std::string case_name(const ::testing::TestParamInfo<Case>& info)
{
    const Case& c = info.param;
    return std::to_string(c.dim) + "D_" + c.integrator + (c.contact ? "_contact" : "_free") + "_stride"
        + (c.stride ? std::to_string(c.stride) : std::string("Default"));
}

std::vector<Case> all_cases()
{
    std::vector<Case> cases;
    for (int dim : { 2, 3 })
        for (const char* integrator : { "static", "implicit_euler", "bdf2", "newmark" })
            for (bool contact : { false, true })
                for (int stride : { 3, 0 })
                    cases.push_back({ dim, integrator, contact, stride });
    return cases;
}

/// The gradient of `objective` checkpointed every `stride` steps (the run's own parameters `p`).
ParameterGradient stride_gradient(const Scene& scene, const SimulationParameters& p, const StateObjective& objective,
    const ParameterRequest& request, int stride, CheckpointStatistics& stats)
{
    Simulator sim(scene, p);
    StreamedStateObjective streamed { objective };
    CheckpointSettings settings;
    settings.mode = CheckpointSettings::Mode::STRIDE;
    settings.stride = stride;
    return checkpointed_gradient(sim, streamed.callbacks(), request, settings, &stats);
}

ParameterRequest every_block(bool dynamic)
{
    ParameterRequest request;
    request.rest_positions = request.lame = request.density = request.prescribed = true;
    request.initial_displacement = true;
    request.initial_velocity = dynamic;
    return request;
}

} // namespace

class CheckpointedGradient : public ::testing::TestWithParam<Case> { };

TEST_P(CheckpointedGradient, MatchesFullMemoryWithFewerStoredStates)
{
    const Case& c = GetParam();
    const Scene scene = make_scene(c.contact ? landing_box(c.dim, c.integrator) : moving_bar(c.dim, c.integrator));

    Simulator full(scene);
    full.run();
    ASSERT_EQ(full.trajectory().final_status, StepStatus::CONVERGED) << full.trajectory().failure_message;
    ASSERT_EQ(full.steps_done(), STEPS);
    if (c.contact) {
        // Without contacts the contact paths of the recomputation would go unchecked.
        int touching = 0;
        for (const StepRecord& r : full.trajectory().steps)
            touching += r.active_contacts > 0;
        ASSERT_GT(touching, STEPS / 2);
    }
    const StateObjective objective(STEPS, full.mesh().num_dofs(), full.bbox_diagonal(), scene.time.dt, 11);
    const ParameterRequest request = every_block(full.dynamic());
    const ParameterGradient reference = adjoint_gradient(full, objective.seed(full), request);

    Simulator sim(scene);
    StreamedStateObjective streamed { objective };
    CheckpointSettings settings;
    settings.mode = CheckpointSettings::Mode::STRIDE;
    settings.stride = c.stride;
    CheckpointStatistics stats;
    const ParameterGradient grad = checkpointed_gradient(sim, streamed.callbacks(), request, settings, &stats);

    EXPECT_NEAR(streamed.value, objective.value(full), 1e-12 * std::abs(objective.value(full)));
    double worst = 0;
    const auto check = [&worst](const char* name, const VectorXd& got, const VectorXd& want) {
        ASSERT_EQ(got.size(), want.size()) << name;
        ASSERT_GT(want.norm(), 0) << name << ": an empty block would make the comparison vacuous";
        EXPECT_LT(relative_difference(got, want), 1e-10) << name;
        worst = std::max(worst, relative_difference(got, want));
    };
    check("rest_positions", grad.rest_positions, reference.rest_positions);
    check("mu", grad.mu, reference.mu);
    check("lambda", grad.lambda, reference.lambda);
    check("density", grad.density, reference.density);
    check("initial_displacement", grad.initial_displacement, reference.initial_displacement);
    if (request.initial_velocity)
        check("initial_velocity", grad.initial_velocity, reference.initial_velocity);
    check("prescribed", grad.prescribed.reshaped(), reference.prescribed.reshaped());

    // Memory: the schedule's bound, and fewer records than steps; the recomputation it costs.
    const int h = sim.history();
    const int s = c.stride ? c.stride : int(std::ceil(std::sqrt(double(h) * STEPS)));
    std::printf("  T %d  stride %d  stored states %d (bound %d, %zu bytes)  recomputed %d  largest relative "
                "difference %.2e\n",
        STEPS, stats.stride, stats.peak_stored_states, stats.bound_stored_states, stats.peak_stored_bytes,
        stats.recomputed_steps, worst);
    EXPECT_EQ(stats.stride, s);
    EXPECT_EQ(stats.bound_stored_states, checkpoint_memory_bound(STEPS, s, h));
    EXPECT_LE(stats.peak_stored_states, stats.bound_stored_states);
    EXPECT_LT(stats.peak_stored_states, STEPS);
    EXPECT_GT(stats.peak_stored_bytes, 0u);
    const int m = (STEPS + s - 1) / s - 1;
    EXPECT_EQ(stats.checkpoints, m);
    EXPECT_EQ(stats.recomputed_steps, m * (s - h));
    EXPECT_GT(stats.cost_ratio, 1.0);
    // Seeds came segment by segment, from the last one down to the initial state.
    ASSERT_EQ(streamed.segments.size(), size_t(m + 1));
    EXPECT_EQ(streamed.segments.front().second, STEPS);
    EXPECT_EQ(streamed.segments.back().first, 0);

    // Afterwards the simulator stands at the final state; only the final records hold theirs.
    EXPECT_EQ(sim.current_step(), STEPS);
    EXPECT_EQ((sim.positions() - full.positions()).lpNorm<Eigen::Infinity>(), 0.0);
    for (int k = 1; k <= STEPS; ++k)
        EXPECT_EQ(sim.trajectory().steps[size_t(k - 1)].holds_state(), k > STEPS - h) << "step " << k;
}

INSTANTIATE_TEST_SUITE_P(Schedules, CheckpointedGradient, ::testing::ValuesIn(all_cases()), case_name);

TEST(CheckpointedGradient, NoneModeHoldsEveryRecordAndRecomputesNothing)
{
    const Scene scene = make_scene(moving_bar(2, "bdf2"));
    Simulator full(scene);
    full.run();
    const StateObjective objective(STEPS, full.mesh().num_dofs(), full.bbox_diagonal(), scene.time.dt, 3);
    const ParameterRequest request = every_block(true);
    const ParameterGradient reference = adjoint_gradient(full, objective.seed(full), request);

    Simulator sim(scene);
    StreamedStateObjective streamed { objective };
    CheckpointStatistics stats;
    const ParameterGradient grad = checkpointed_gradient(sim, streamed.callbacks(), request, {}, &stats);
    // One segment, the whole run: the very same arithmetic as adjoint_gradient().
    EXPECT_EQ((grad.rest_positions - reference.rest_positions).lpNorm<Eigen::Infinity>(), 0.0);
    EXPECT_EQ((grad.mu - reference.mu).lpNorm<Eigen::Infinity>(), 0.0);
    EXPECT_EQ(stats.peak_stored_states, STEPS);
    EXPECT_EQ(stats.recomputed_steps, 0);
    EXPECT_EQ(streamed.segments.size(), 1u);
    for (const StepRecord& r : sim.trajectory().steps)
        EXPECT_TRUE(r.holds_state());
}

TEST(CheckpointedGradient, FrictionRecordsAreRecomputedToo)
{
    // The lagged friction data of a released record comes back with its recomputation;
    // the comparison is with the full-memory sweep, whatever the friction adjoint computes.
    // BDF2 reads two past states and the friction of step k is lagged at x_{k-1}: both
    // must come back from a checkpoint.
    for (const char* integrator : { "implicit_euler", "bdf2" }) {
        SCOPED_TRACE(integrator);
        json scene_json = landing_box(2, integrator);
        scene_json["friction"] = { { "coefficient", 0.3 }, { "iterations", 1 } };
        const Scene scene = make_scene(scene_json);
        Simulator full(scene);
        full.run();
        ASSERT_EQ(full.steps_done(), STEPS) << full.trajectory().failure_message;
        ASSERT_FALSE(full.trajectory().steps.back().friction.empty());
        const StateObjective objective(STEPS, full.mesh().num_dofs(), full.bbox_diagonal(), scene.time.dt, 5);
        ParameterRequest request = every_block(true);
        request.friction = true;
        const ParameterGradient reference = adjoint_gradient(full, objective.seed(full), request);

        CheckpointStatistics stats;
        const ParameterGradient grad = stride_gradient(scene, SimulationParameters {}, objective, request, 4, stats);
        EXPECT_GT(stats.recomputed_steps, 0);
        ASSERT_GT(reference.friction.norm(), 0);
        EXPECT_LT(relative_difference(grad.friction, reference.friction), 1e-10);
        EXPECT_LT(relative_difference(grad.initial_velocity, reference.initial_velocity), 1e-10);
        // Written reason for 1e-9 on the rest positions: the plane point's entry (a rest
        // position of the obstacle vertex) sums friction terms of stiffness mu lam 2/eps
        // (eps = eps_v h = 5e-6 m) that cancel to a value 1e5 times smaller, and the sweep
        // adds a segment's seed after the later segment's pushes at segment boundaries
        // (another summation order): 6e-11 (implicit Euler) and 1.1e-10 (BDF2) relative,
        // every other block 1e-15. The states themselves are bit-identical.
        EXPECT_LT(relative_difference(grad.rest_positions, reference.rest_positions), 1e-9);
    }
}

TEST(CheckpointedGradient, SubsteppedDynamicRecordsAreRecomputedWithTheirSubsteps)
{
    // Dynamic steps taken in sub-steps (SimulationParameters::substeps; time.adaptive records them
    // the same way): a released record is recomputed through the sub-steps it took, and its
    // intermediate states come back for the sweep. Compared with the full-memory sweep.
    for (const char* integrator : { "implicit_euler", "newmark" }) {
        SCOPED_TRACE(integrator);
        const Scene scene = make_scene(landing_box(2, integrator));
        SimulationParameters p;
        for (int k = 1; k <= STEPS; ++k)
            p.substeps.push_back({ (k - 0.6) * scene.time.dt, (k - 0.25) * scene.time.dt, k * scene.time.dt });
        Simulator full(scene, p);
        full.run();
        ASSERT_EQ(full.steps_done(), STEPS) << full.trajectory().failure_message;
        ASSERT_EQ(full.trajectory().steps.back().path.size(), 2u);
        const StateObjective objective(STEPS, full.mesh().num_dofs(), full.bbox_diagonal(), scene.time.dt, 5);
        const ParameterRequest request = every_block(true);
        const ParameterGradient reference = adjoint_gradient(full, objective.seed(full), request);

        CheckpointStatistics stats;
        const ParameterGradient grad = stride_gradient(scene, p, objective, request, 4, stats);
        EXPECT_GT(stats.recomputed_steps, 0);
        EXPECT_LT(stats.peak_stored_states, STEPS);
        EXPECT_LT(relative_difference(grad.rest_positions, reference.rest_positions), 1e-10);
        EXPECT_LT(relative_difference(grad.mu, reference.mu), 1e-10);
        EXPECT_LT(relative_difference(grad.density, reference.density), 1e-10);
        EXPECT_LT(relative_difference(grad.initial_velocity, reference.initial_velocity), 1e-10);
    }
}

TEST(CheckpointedGradient, MemoryBound)
{
    // h (ceil(T/s) - 1) + s, and never more than T.
    EXPECT_EQ(checkpoint_memory_bound(16, 4, 1), 7);
    EXPECT_EQ(checkpoint_memory_bound(16, 4, 2), 10);
    EXPECT_EQ(checkpoint_memory_bound(14, 3, 1), 7);
    EXPECT_EQ(checkpoint_memory_bound(100, 10, 1), 19);
    EXPECT_EQ(checkpoint_memory_bound(5, 1, 2), 5);
    EXPECT_EQ(checkpoint_memory_bound(0, 1, 1), 0);
}

TEST(CheckpointedGradient, RejectsASteppedSimulator)
{
    Simulator sim(make_scene(moving_bar(2, "implicit_euler")));
    sim.step();
    const StateObjective objective(STEPS, sim.mesh().num_dofs(), 1.0, 0.01, 1);
    StreamedStateObjective streamed { objective };
    EXPECT_THROW(checkpointed_gradient(sim, streamed.callbacks(), every_block(true), {}), std::invalid_argument);
}

/// Restoring a committed step and recomputing from it refills the released records
/// with the states of the first run, bit for bit (the forward is deterministic).
class RecomputeSteps : public ::testing::TestWithParam<std::tuple<std::string, bool>> { };

TEST_P(RecomputeSteps, RefillsReleasedRecordsBitForBit)
{
    const auto& [integrator, contact] = GetParam();
    Simulator sim(make_scene(contact ? landing_box(2, integrator) : moving_bar(2, integrator)));
    sim.run();
    ASSERT_EQ(sim.steps_done(), STEPS) << sim.trajectory().failure_message;
    std::vector<StepRecord> first_run = sim.trajectory().steps;
    const int from = 5, to = 11;
    for (int k = from + 1; k <= to; ++k)
        sim.release_state(k);
    EXPECT_FALSE(sim.trajectory().steps[size_t(to - 1)].holds_state());
    EXPECT_THROW(sim.step_problem(to), std::exception);
    sim.restore_state(from);
    EXPECT_EQ(sim.current_step(), from);
    sim.recompute_steps(to);
    EXPECT_EQ(sim.current_step(), to);
    for (int k = from + 1; k <= to; ++k) {
        const StepRecord& again = sim.trajectory().steps[size_t(k - 1)];
        const StepRecord& before = first_run[size_t(k - 1)];
        ASSERT_TRUE(again.holds_state()) << "step " << k;
        EXPECT_EQ((again.positions - before.positions).lpNorm<Eigen::Infinity>(), 0.0) << "step " << k;
        EXPECT_EQ((again.velocities - before.velocities).lpNorm<Eigen::Infinity>(), 0.0) << "step " << k;
        EXPECT_EQ((again.accelerations - before.accelerations).lpNorm<Eigen::Infinity>(), 0.0) << "step " << k;
        EXPECT_EQ(again.contacts.size(), before.contacts.size()) << "step " << k;
        EXPECT_EQ(again.newton_iterations, before.newton_iterations) << "step " << k;
    }
    // The trajectory's totals are the first run's: recomputation is not counted as forward work.
    int iterations = 0;
    for (const StepRecord& r : first_run)
        iterations += r.newton_iterations;
    EXPECT_EQ(sim.trajectory().newton_iterations, iterations);
    // A record that restore_state() needs must hold its state.
    sim.release_state(8);
    EXPECT_THROW(sim.restore_state(8), std::logic_error);
}

INSTANTIATE_TEST_SUITE_P(Integrators, RecomputeSteps,
    ::testing::Combine(::testing::Values("static", "implicit_euler", "bdf2", "newmark"), ::testing::Bool()),
    [](const auto& info) { return std::get<0>(info.param) + (std::get<1>(info.param) ? "_contact" : "_free"); });
