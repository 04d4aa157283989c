// StreamedObjectiveAdapter (objectives/streamed.hpp): any objective through the
// checkpointed adjoint gives the full-memory value and gradient to round-off,
// copying only the states the objective declares (Objective::states_read()).

#include "objectives/streamed.hpp"

#include "objective_fd.hpp"
#include "objectives/objective_json.hpp"

using namespace diffipc;
using nlohmann::json;

namespace {

constexpr int STEPS = 9;

json scene(const std::string& integrator)
{
    json s = test::cantilever_scene(2);
    s["time"] = { { "integrator", integrator }, { "dt", 0.01 }, { "steps", STEPS } };
    s["solver"] = { { "residual_tolerance", 1e-11 } };
    return s;
}

struct Case {
    std::string name;
    json objective;
    int stored_states; ///< states whose x, v the adapter keeps
};

std::vector<Case> cases()
{
    const json markers = { { "type", "markers" }, { "vertices", { 3, 14 } },
        { "targets", { { { 1.0, 0.1 }, { 0.2, 0.3 } }, { { 1.0, 0.0 }, { 0.2, 0.2 } } } }, { "steps", { 2, STEPS } } };
    const json com
        = { { "type", "center_of_mass" }, { "targets", { { 0.5, 0.1 }, { 0.5, 0.05 } } }, { "steps", { 0, 5 } } };
    return {
        { "stress_max_p", { { "type", "stress_norm" }, { "p", 6 }, { "time", { { "max_p", 8 } } } }, STEPS + 1 },
        { "elastic_energy_final", { { "type", "elastic_energy" }, { "time", "final" } }, 1 },
        { "markers", markers, 2 },
        { "sum",
            { { "type", "sum" },
                { "terms",
                    { { { "weight", 2.0 }, { "objective", markers } },
                        { { "weight", 0.5 }, { "objective", com } } } } },
            4 },
        { "kinetic_trapezoid_power",
            { { "type", "power" }, { "q", 2 },
                { "objective", { { "type", "kinetic_energy" }, { "time", "trapezoid" } } } },
            STEPS + 1 },
        { "boundary_smoothness", { { "type", "boundary_smoothness" } }, 0 },
    };
}

ParameterRequest request()
{
    ParameterRequest r;
    r.rest_positions = r.lame = r.density = r.initial_velocity = r.initial_displacement = true;
    return r;
}

/// |a - b| <= 1e-10 |b| for every requested block (an empty block reads as 0).
void expect_same_gradient(const ParameterGradient& a, const ParameterGradient& b)
{
    for (test::Block block : { test::Block::REST_POSITIONS, test::Block::MU, test::Block::LAMBDA, test::Block::DENSITY,
             test::Block::INITIAL_DISPLACEMENT, test::Block::INITIAL_VELOCITY }) {
        const VectorXd& ga = *test::block_vector(a, block);
        const VectorXd& gb = *test::block_vector(b, block);
        ASSERT_EQ(ga.size(), gb.size()) << test::block_name(block);
        if (gb.size() == 0)
            continue;
        EXPECT_LE((ga - gb).norm(), 1e-10 * gb.norm()) << test::block_name(block) << " |g| " << gb.norm();
    }
}

} // namespace

class Streamed : public ::testing::TestWithParam<std::string> { };

TEST_P(Streamed, CheckpointedEqualsFullMemory)
{
    const Scene sc = test::make_scene(scene(GetParam()));
    for (const Case& c : cases()) {
        SCOPED_TRACE(c.name);
        const double weight = 0.7;
        Simulator full(sc);
        full.run();
        const auto J = parse_objective(c.objective, "objective", full);
        const double value = J->value(full, full.trajectory());
        StateSeed seed;
        seed.resize(STEPS);
        J->add_gradient(full, full.trajectory(), request(), weight, seed);
        const ParameterGradient expected = adjoint_gradient(full, seed, request());

        Simulator sim(sc);
        StreamedObjectiveAdapter adapter(*J, request(), weight);
        EXPECT_THROW(adapter.value(), std::logic_error);
        CheckpointStatistics stats;
        const ParameterGradient g = checkpointed_gradient(
            sim, adapter.streamed(), request(), { CheckpointSettings::Mode::STRIDE, 3 }, &stats);
        EXPECT_NEAR(adapter.value(), value, 1e-12 * std::abs(value));
        expect_same_gradient(g, expected);
        EXPECT_EQ(adapter.stored_states(), c.stored_states);
        EXPECT_EQ(adapter.stored_bytes(), size_t(c.stored_states) * 2 * sizeof(double) * size_t(sim.mesh().num_dofs()));
        EXPECT_LT(stats.peak_stored_states, STEPS);
        EXPECT_GT(stats.recomputed_steps, 0);
    }
}

INSTANTIATE_TEST_SUITE_P(Integrators, Streamed, ::testing::Values("implicit_euler", "bdf2"));

TEST(Streamed, UndeclaredStateIsAnErrorNotGarbage)
{
    // An objective that declares fewer states than it reads: the adapter's copy lacks
    // them and the read throws instead of seeing an empty vector.
    struct Liar : Objective {
        std::string name() const override { return "liar"; }
        double value(const Simulator&, const Trajectory& trajectory) const override
        {
            return state_positions(trajectory, 1).sum();
        }
        void add_gradient(
            const Simulator&, const Trajectory&, const ParameterRequest&, double, StateSeed&) const override
        {
        }
        std::vector<int> states_read(int steps) const override { return { steps }; }
    } liar;
    Simulator sim(test::make_scene(scene("implicit_euler")));
    StreamedObjectiveAdapter adapter(liar, request());
    EXPECT_THROW(checkpointed_gradient(sim, adapter.streamed(), request(), { CheckpointSettings::Mode::STRIDE, 3 }),
        std::logic_error);
}

TEST(Streamed, StateOutsideTheRunIsAnError)
{
    struct Beyond : Objective {
        std::string name() const override { return "beyond"; }
        double value(const Simulator&, const Trajectory&) const override { return 0; }
        void add_gradient(
            const Simulator&, const Trajectory&, const ParameterRequest&, double, StateSeed&) const override
        {
        }
        std::vector<int> states_read(int steps) const override { return { steps + 1 }; }
    } beyond;
    Simulator sim(test::make_scene(scene("implicit_euler")));
    StreamedObjectiveAdapter adapter(beyond, request());
    EXPECT_THROW(checkpointed_gradient(sim, adapter.streamed(), request(), {}), std::out_of_range);
}
