#include "objectives/stress_norm.hpp"

#include "forward/common/threads.hpp"
#include "objective_fd.hpp"
#include "objectives/time_aggregation.hpp"

#include <Eigen/Dense>
#include <tbb/task_arena.h>

using namespace diffipc;

namespace {

struct Case {
    int dim;
    std::string model;
    StressNormType norm;
    StressMeasure stress;
    double p;
    bool normalized;
    bool subset; ///< every other element only
};

std::string case_name(const ::testing::TestParamInfo<Case>& info)
{
    const Case& c = info.param;
    return std::to_string(c.dim) + "d_" + c.model + (c.norm == StressNormType::VON_MISES ? "_vm" : "_frob")
        + (c.stress == StressMeasure::CAUCHY ? "_cauchy" : "_piola") + "_p" + std::to_string(int(c.p * 10))
        + (c.normalized ? "_normalized" : "") + (c.subset ? "_subset" : "");
}

StressNormOptions options(const Case& c, const Simulator& sim)
{
    StressNormOptions o;
    o.p = c.p;
    o.norm = c.norm;
    o.stress = c.stress;
    o.normalized = c.normalized;
    if (c.subset)
        for (Index e = 0; e < sim.mesh().num_elements(); e += 2)
            o.elements.push_back(e);
    return o;
}

class StressNormGradient : public ::testing::TestWithParam<Case> { };

TEST_P(StressNormGradient, MatchesFiniteDifferences)
{
    const Case c = GetParam();
    const test::Run run = test::run_scene(test::cantilever_scene(c.dim, c.model));
    // Summed over all states so that every state's derivative is exercised.
    const TimeAggregation J(std::make_unique<StressNorm>(options(c, *run.sim)), TimeMode::SUM, 8, true);
    ASSERT_GT(J.value(*run.sim, run.trajectory), 0);
    test::check_state_gradient(J, run);
    test::check_parameter_gradient(J, run, test::Block::REST_POSITIONS);
    test::check_parameter_gradient(J, run, test::Block::MU);
    // The von Mises norm of an isotropic stress is zero, and for the linear law (first Piola)
    // and the neo-Hookean laws (Cauchy) the lambda term of the stress is isotropic: in 3D
    // the lambda partial then vanishes identically and the finite difference is round-off
    // (~1e-10 |J| for a 1e-6 relative step). The floor 1e-3 |J| makes the check absolute
    // at 1e-9 |J| there, a thousandth of the natural scale |J| of this derivative.
    test::check_parameter_gradient(J, run, test::Block::LAMBDA, 23, 1e-6, 1e-3);
    test::check_parameter_gradient(J, run, test::Block::DENSITY);
}

using SN = StressNormType;
using SM = StressMeasure;
INSTANTIATE_TEST_SUITE_P(Cases, StressNormGradient,
    ::testing::Values(Case { 2, "neo_hookean", SN::VON_MISES, SM::CAUCHY, 8, false, false },
        Case { 2, "linear", SN::VON_MISES, SM::CAUCHY, 8, false, false },
        Case { 2, "stvk", SN::VON_MISES, SM::CAUCHY, 8, false, false },
        Case { 2, "stable_neo_hookean", SN::VON_MISES, SM::CAUCHY, 8, false, false },
        Case { 2, "neo_hookean", SN::FROBENIUS, SM::FIRST_PIOLA, 2, false, false },
        Case { 2, "stvk", SN::VON_MISES, SM::FIRST_PIOLA, 4, true, false },
        Case { 2, "neo_hookean", SN::FROBENIUS, SM::CAUCHY, 1.5, false, true },
        Case { 3, "neo_hookean", SN::VON_MISES, SM::CAUCHY, 8, false, false },
        Case { 3, "stvk", SN::FROBENIUS, SM::FIRST_PIOLA, 3, true, false },
        Case { 3, "linear", SN::VON_MISES, SM::FIRST_PIOLA, 6, false, true },
        Case { 3, "stable_neo_hookean", SN::FROBENIUS, SM::CAUCHY, 2, false, false },
        Case { 3, "neo_hookean", SN::VON_MISES, SM::CAUCHY, 16, true, false }),
    case_name);

/// Element stresses from the elastic potential (an independent path): P and F per element.
struct ElementStress {
    Eigen::MatrixXd P, F;
    double volume;
};

std::vector<ElementStress> element_stresses(const Simulator& sim, const VectorXd& x)
{
    const int d = sim.mesh().dim;
    const MatrixXd P = sim.elastic().element_stresses(x);
    std::vector<ElementStress> out;
    for (Index e = 0; e < sim.mesh().num_elements(); ++e) {
        ElementStress s;
        const VectorXd row = P.row(e).transpose(); // row-major flattening of P_e
        s.P = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
            row.data(), d, d);
        Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> F(d, d);
        sim.space().deformation_gradient(e, x, F.data());
        s.F = F;
        s.volume = sim.space().rest_volume(e);
        out.push_back(s);
    }
    return out;
}

double final_stress_norm(const test::Run& run, const StressNormOptions& o)
{
    return StressNorm(o).value(*run.sim,
        { run.steps(), 0.0, state_positions(run.trajectory, run.steps()),
            state_velocities(run.trajectory, run.steps()) });
}

TEST(StressNorm, FrobeniusOfFirstPiolaMatchesElasticPotential)
{
    for (int dim : { 2, 3 }) {
        const test::Run run = test::run_scene(test::cantilever_scene(dim));
        double sum = 0;
        for (const auto& s : element_stresses(*run.sim, state_positions(run.trajectory, run.steps())))
            sum += s.volume * s.P.squaredNorm();
        StressNormOptions o;
        o.p = 2;
        o.norm = StressNormType::FROBENIUS;
        o.stress = StressMeasure::FIRST_PIOLA;
        EXPECT_NEAR(final_stress_norm(run, o), std::sqrt(sum), 1e-12 * std::sqrt(sum)) << dim;
    }
}

TEST(StressNorm, VonMisesOfCauchyStressByHand)
{
    for (int dim : { 2, 3 }) {
        const test::Run run = test::run_scene(test::cantilever_scene(dim));
        double sum = 0;
        for (const auto& s : element_stresses(*run.sim, state_positions(run.trajectory, run.steps()))) {
            const Eigen::MatrixXd sigma = s.P * s.F.transpose() / s.F.determinant();
            double vm2;
            if (dim == 3) {
                const Eigen::MatrixXd dev = sigma - sigma.trace() / 3 * Eigen::MatrixXd::Identity(3, 3);
                vm2 = 1.5 * dev.squaredNorm();
            } else {
                // The documented plane definition: sigma_zz = 0.
                const double a = sigma(0, 0), b = sigma(1, 1), c = sigma(0, 1);
                vm2 = a * a - a * b + b * b + 3 * c * c;
            }
            sum += s.volume * vm2;
        }
        StressNormOptions o;
        o.p = 2;
        EXPECT_NEAR(final_stress_norm(run, o), std::sqrt(sum), 1e-12 * std::sqrt(sum)) << dim;
    }
}

TEST(StressNorm, LargeNormalizedPApproachesMaximumFromBelow)
{
    const test::Run run = test::run_scene(test::cantilever_scene(2));
    const VectorXd& x = state_positions(run.trajectory, run.steps());
    double max_vm = 0, total_volume = 0, min_volume = 1e300;
    for (const auto& s : element_stresses(*run.sim, x)) {
        const Eigen::MatrixXd sigma = s.P * s.F.transpose() / s.F.determinant();
        const double a = sigma(0, 0), b = sigma(1, 1), c = sigma(0, 1);
        max_vm = std::max(max_vm, std::sqrt(a * a - a * b + b * b + 3 * c * c));
        total_volume += s.volume;
        min_volume = std::min(min_volume, s.volume);
    }
    StressNormOptions o;
    o.normalized = true;
    double previous = 0;
    for (double p : { 2.0, 8.0, 32.0, 128.0, 1024.0 }) {
        o.p = p;
        const double J = final_stress_norm(run, o);
        // Power means increase with p and are bounded by the maximum; the element of largest
        // stress alone gives the lower bound (|e*| / V)^{1/p} max.
        EXPECT_GE(J, previous) << p;
        EXPECT_LE(J, max_vm * (1 + 1e-12)) << p;
        EXPECT_GE(J, std::pow(min_volume / total_volume, 1.0 / p) * max_vm * (1 - 1e-12)) << p;
        previous = J;
    }
    EXPECT_NEAR(previous, max_vm, 0.01 * max_vm); // p = 1024: within (1/16)^{1/1024} - 1 ~ 0.3%
}

TEST(StressNorm, SubsetsAddInThePthPower)
{
    const test::Run run = test::run_scene(test::cantilever_scene(3));
    StressNormOptions all, even, odd;
    for (auto* o : { &all, &even, &odd })
        o->p = 5;
    for (Index e = 0; e < run.sim->mesh().num_elements(); ++e)
        (e % 2 ? odd : even).elements.push_back(e);
    const double J = final_stress_norm(run, all), Je = final_stress_norm(run, even), Jo = final_stress_norm(run, odd);
    EXPECT_NEAR(std::pow(J, 5), std::pow(Je, 5) + std::pow(Jo, 5), 1e-12 * std::pow(J, 5));
}

TEST(StressNorm, UnstressedStateHasZeroValueAndGradient)
{
    const test::Run run = test::run_scene(test::cantilever_scene(2));
    Trajectory t = run.trajectory;
    t.steps.back().positions = flatten(run.sim->mesh().rest_positions);
    const TimeAggregation J(std::make_unique<StressNorm>(StressNormOptions {}), TimeMode::FINAL);
    EXPECT_EQ(J.value(*run.sim, t), 0.0);
    StateSeed seed;
    seed.resize(run.steps());
    ParameterRequest all;
    all.rest_positions = all.lame = all.density = true;
    J.add_gradient(*run.sim, t, all, 1.0, seed);
    for (const VectorXd& g : seed.positions)
        EXPECT_TRUE(g.size() == 0 || (g.array() == 0).all());
    EXPECT_TRUE(seed.explicit_partials.rest_positions.size() == 0
        || (seed.explicit_partials.rest_positions.array() == 0).all());
}

TEST(StressNorm, RejectsPBelowOne)
{
    StressNormOptions o;
    o.p = 0.5;
    EXPECT_THROW(StressNorm { o }, std::invalid_argument);
}

} // namespace

// The elements run in parallel (fixed-tree sums, per-vertex gathers in element order):
// value and every gradient the same to the bit with 1 and 4 threads, on a mesh large
// enough for several blocks, with an element listed twice.
TEST(StressNorm, SameBitsForAnyThreadCount)
{
    nlohmann::json scene = test::box_scene(3, { 1.0, 0.25, 0.25 }, { 24, 6, 6 }, "neo_hookean", 1e5, 0.3, 1000);
    scene["bodies"][0]["initial_velocity"] = { 0.1, -0.5, 0.2 };
    scene["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", 2 } };
    const test::Run run = test::run_scene(scene);
    StressNormOptions o;
    o.p = 6;
    o.stress = StressMeasure::CAUCHY;
    o.norm = StressNormType::VON_MISES;
    for (Index e = 0; e < run.sim->mesh().num_elements(); e += 3)
        o.elements.push_back(e);
    o.elements.push_back(0);
    ASSERT_GT(o.elements.size(), 1000u);
    const TimeAggregation J(std::make_unique<StressNorm>(o), TimeMode::FINAL);
    ParameterRequest all;
    all.rest_positions = all.lame = all.density = true;
    struct Result {
        double value = 0;
        StateSeed seed;
    };
    std::vector<Result> results;
    for (int threads : { 1, 4 }) {
        set_threads(threads, ThreadSource::EXPLICIT, "test");
        tbb::task_arena arena(threads);
        Result r;
        r.seed.resize(run.steps());
        arena.execute([&] {
            r.value = J.value(*run.sim, run.trajectory);
            J.add_gradient(*run.sim, run.trajectory, all, 1.0, r.seed);
        });
        EXPECT_EQ(arena.max_concurrency(), threads);
        results.push_back(std::move(r));
    }
    set_threads(0, ThreadSource::EXPLICIT, "test");
    EXPECT_EQ(results[0].value, results[1].value);
    ASSERT_EQ(results[0].seed.positions.size(), results[1].seed.positions.size());
    for (size_t k = 0; k < results[0].seed.positions.size(); ++k)
        EXPECT_EQ(results[0].seed.positions[k], results[1].seed.positions[k]) << "step " << k;
    EXPECT_GT(results[0].seed.positions.back().norm(), 0);
    EXPECT_EQ(results[0].seed.explicit_partials.rest_positions, results[1].seed.explicit_partials.rest_positions);
    EXPECT_EQ(results[0].seed.explicit_partials.mu, results[1].seed.explicit_partials.mu);
    EXPECT_EQ(results[0].seed.explicit_partials.lambda, results[1].seed.explicit_partials.lambda);
    EXPECT_GT(results[0].seed.explicit_partials.mu.norm(), 0);
}
