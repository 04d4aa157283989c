#pragma once
// Shared by the objective tests: small deforming runs and central finite-difference
// checks of an objective's state derivatives and explicit parameter partials.
//
// Finite differences: the fourth-order central difference
//   (8 (J(p + h d) - J(p - h d)) - (J(p + 2h d) - J(p - 2h d))) / (12 h)
// in a random direction d (entries in [-1, 1], fixed seeds). The runs start from a random
// displacement of 1e-2 m on elements about 0.25 m across (strains of a few percent). Two error
// sources bound the step: a norm of the stress curves on the scale of the stress itself, so
// the truncation error is about (p dF / F_strain)^4 with dF ~ 8 h / m (below 1e-13 for p <= 16
// at h = 1e-6 m); and J's round-off, dominated by the cancellation in F = sum_a x_a G_a^T with
// x ~ 1 m (~1e-13 relative in the strain), which the difference divides by h. With the
// second-order difference no single h kept both below 1e-7 for every objective here; the
// fourth-order one at h = 1e-6 m (positions and rest positions) keeps the observed errors near
// 1e-8 or below. Velocities are perturbed by 1e-6 max(1, |v|) (the objectives are at most
// quadratic in v); Lame parameters and densities by 1e-6 relative, element by element.

#include "adjoint/parameter_blocks.hpp"
#include "forward/test_utils.hpp"
#include "objectives/objective.hpp"
#include "objectives/objective_json.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <sstream>

namespace diffipc::test {

/// A box [0, 1] x [0, 0.25] (x [0, 0.25]) clamped at x = 0 under gravity and a
/// time-dependent traction at x = 1, implicit Euler, 3 steps of 0.01 s.
inline nlohmann::json cantilever_scene(
    int dim, const std::string& model = "neo_hookean", const std::string& mass = "lumped")
{
    const bool three = dim == 3;
    nlohmann::json s
        = box_scene(dim, three ? std::vector<double> { 1.0, 0.25, 0.25 } : std::vector<double> { 1.0, 0.25 },
            three ? std::vector<int> { 3, 1, 1 } : std::vector<int> { 4, 2 }, model, 1e5, 0.3, 1000);
    s["bodies"][0]["initial_velocity"]
        = three ? std::vector<double> { 0.1, -0.5, 0.2 } : std::vector<double> { 0.1, -0.5 };
    s["gravity"] = three ? std::vector<double> { 0, -9.81, 0 } : std::vector<double> { 0, -9.81 };
    const std::vector<double> lo(size_t(dim), -0.01);
    std::vector<double> hi(size_t(dim), 0.26);
    hi[0] = 0.01;
    s["dirichlet"] = { { { "body", 0 }, { "region", region(lo, hi) },
        { "displacement", three ? nlohmann::json { 0, 0, 0 } : nlohmann::json { 0, 0 } } } };
    std::vector<double> end_lo(size_t(dim), -0.01), end_hi(size_t(dim), 0.26);
    end_lo[0] = 0.99;
    end_hi[0] = 1.01;
    const nlohmann::json traction
        = three ? nlohmann::json { "0", "-2e3*(1+10*t)", "5e2" } : nlohmann::json { "0", "-2e3*(1+10*t)" };
    s["neumann"] = { { { "body", 0 }, { "region", region(end_lo, end_hi) }, { "traction", traction } } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", 0.01 }, { "steps", 3 } };
    s["mass"] = mass;
    return s;
}

/// A simulation run from a random initial displacement (so that every state, the
/// initial one included, is stressed) and the trajectory it recorded.
struct Run {
    nlohmann::json scene_json;
    std::unique_ptr<Simulator> sim;
    Trajectory trajectory;

    int dim() const { return sim->mesh().dim; }
    Index dofs() const { return sim->mesh().num_dofs(); }
    int steps() const { return num_steps(trajectory); }
};

inline Run run_scene(const nlohmann::json& scene_json, unsigned seed = 7)
{
    Run r;
    r.scene_json = scene_json;
    r.sim = std::make_unique<Simulator>(make_scene(scene_json));
    const VectorXd X = flatten(r.sim->mesh().rest_positions);
    const VectorXd v0 = r.sim->velocities();
    r.sim->set_initial_state(X + 1e-2 * random_vector(X.size(), seed), v0 + 0.1 * random_vector(X.size(), seed + 1));
    r.trajectory = r.sim->run();
    EXPECT_EQ(r.trajectory.final_status, StepStatus::CONVERGED);
    EXPECT_EQ(int(r.trajectory.steps.size()), r.sim->scene().time.steps);
    return r;
}

/// A periodic cell's run from its own initial state (a cell starts at rest), expected to converge.
inline Run run_cell(const nlohmann::json& scene_json)
{
    Run r;
    r.scene_json = scene_json;
    r.sim = std::make_unique<Simulator>(make_scene(scene_json));
    r.trajectory = r.sim->run();
    EXPECT_EQ(r.trajectory.final_status, StepStatus::CONVERGED) << r.trajectory.failure_message;
    return r;
}

/// The message of the InputError that parsing objective `j` (field "objective") raises, or "no error".
inline std::string objective_error(const nlohmann::json& j, const Simulator& sim)
{
    try {
        parse_objective(j, "objective", sim);
    } catch (const InputError& e) {
        return std::string(e.what());
    }
    return "no error";
}

/// |fd - analytic| <= tol * max(|fd|, |analytic|, floor).
inline ::testing::AssertionResult fd_agrees(double fd, double analytic, double tol, double floor = 0)
{
    const double err = std::abs(fd - analytic), ref = std::max({ std::abs(fd), std::abs(analytic), floor });
    if (std::getenv("DIFFIPC_FD_VERBOSE"))
        std::printf(
            "    fd %-24.16g analytic %-24.16g relative error %.3g\n", fd, analytic, err / std::max(ref, 1e-300));
    if (err <= tol * ref)
        return ::testing::AssertionSuccess();
    return ::testing::AssertionFailure() << "finite difference " << fd << " vs analytic " << analytic
                                         << " (relative error " << err / std::max(ref, 1e-300) << ")";
}

/// The scale the gradient checks call add_gradient with (not 1, so that scaling is checked too).
inline constexpr double GRADIENT_SCALE = 1.7;

/// @brief Checks dJ/dx_k and dJ/dv_k for every state k = 0..T against central differences of
/// J on a perturbed copy of the trajectory, one random direction per state and kind.
inline void check_state_gradient(const Objective& J, const Run& run, unsigned seed = 11, double tol = 1e-6)
{
    StateSeed s;
    s.resize(run.steps());
    J.add_gradient(*run.sim, run.trajectory, ParameterRequest {}, GRADIENT_SCALE, s);
    EXPECT_FALSE(s.explicit_partials.rest_positions.size() || s.explicit_partials.mu.size()
        || s.explicit_partials.lambda.size() || s.explicit_partials.density.size())
        << J.name() << ": a parameter block that was not requested";
    for (int k = 0; k <= run.steps(); ++k)
        for (int velocity = 0; velocity < 2; ++velocity) {
            const VectorXd dir = random_vector(run.dofs(), seed + unsigned(10 * k + velocity));
            const VectorXd& state = velocity ? state_velocities(run.trajectory, k) : state_positions(run.trajectory, k);
            const double h = velocity ? 1e-6 * std::max(1.0, state.lpNorm<Eigen::Infinity>()) : 1e-6;
            const double fd = central_difference(
                [&](double eps) {
                    Trajectory t = run.trajectory;
                    VectorXd& x = velocity ? (k == 0 ? t.initial_velocities : t.steps[size_t(k - 1)].velocities)
                                           : (k == 0 ? t.initial_positions : t.steps[size_t(k - 1)].positions);
                    x += eps * dir;
                    return J.value(*run.sim, t);
                },
                h);
            const VectorXd& g = velocity ? s.velocities[size_t(k)] : s.positions[size_t(k)];
            const double analytic = g.size() ? g.dot(dir) / GRADIENT_SCALE : 0.0;
            EXPECT_TRUE(fd_agrees(fd, analytic, tol))
                << J.name() << ": d/d" << (velocity ? "v_" : "x_") << k << " (dim " << run.dim() << ")";
        }
}

/// @brief Checks J's explicit partial in one parameter block against central differences of
/// J on the same (fixed) trajectory, evaluated by a Simulator built with the perturbed
/// parameters (forward/simulation/parameters.hpp). Also checks that add_gradient fills no
/// block that was not requested.
/// @param floor lower bound of the reference magnitude relative to |J| (0: none), for partials
///        that vanish identically, where the finite difference is round-off; the caller says why
inline void check_parameter_gradient(
    const Objective& J, const Run& run, Block block, unsigned seed = 23, double tol = 1e-6, double floor = 0)
{
    const double value = J.value(*run.sim, run.trajectory);
    ParameterRequest request;
    request.rest_positions = block == Block::REST_POSITIONS;
    request.lame = block == Block::MU || block == Block::LAMBDA;
    request.density = block == Block::DENSITY;
    StateSeed s;
    s.resize(run.steps());
    J.add_gradient(*run.sim, run.trajectory, request, GRADIENT_SCALE, s);
    const ParameterGradient& g = s.explicit_partials;
    if (!request.rest_positions)
        EXPECT_EQ(g.rest_positions.size(), 0) << J.name() << ": rest positions not requested";
    if (!request.lame)
        EXPECT_EQ(g.mu.size() + g.lambda.size(), 0) << J.name() << ": Lame parameters not requested";
    if (!request.density)
        EXPECT_EQ(g.density.size(), 0) << J.name() << ": density not requested";
    EXPECT_EQ(g.friction.size() + g.initial_displacement.size() + g.initial_velocity.size() + g.prescribed.size(), 0)
        << J.name() << ": blocks an objective never has";

    const Simulator& sim = *run.sim;
    const SimulationParameters base = sim.parameters();
    const VectorXd& values = *block_vector(base, block);
    // Lengths for rest positions (1e-6 m steps), relative for per-element values.
    const VectorXd dir = block == Block::REST_POSITIONS ? keep_pairing(sim, random_vector(values.size(), seed))
                                                        : random_vector(values.size(), seed).cwiseProduct(values);
    const VectorXd* partial = block_vector(g, block);
    // Rest positions move by 1e-6 m; per-element values by 1e-5 of themselves. J is often exactly
    // quadratic in those (a tracked force is linear in mu and lambda), where a central difference has no
    // truncation error and only rounding: the internal forces that a reaction sums are far larger than
    // its change, and at 1e-6 their rounding alone reached 1.5e-6 of the derivative (3D cantilever,
    // d/dlambda). At 1e-5 the truncation of a non-quadratic J is of order 1e-10 relative.
    const double h = block == Block::REST_POSITIONS ? 1e-6 : 1e-5;
    const double fd = central_difference(
        [&](double eps) {
            Simulator perturbed_sim(make_scene(run.scene_json), perturbed(base, block, dir, MatrixXd(), eps));
            return J.value(perturbed_sim, run.trajectory);
        },
        h);
    const double analytic = partial->size() ? partial->dot(dir) / GRADIENT_SCALE : 0.0;
    EXPECT_TRUE(fd_agrees(fd, analytic, tol, floor * std::abs(value)))
        << J.name() << ": d/d" << block_name(block) << " (dim " << run.dim() << ")";
}

/// All four parameter blocks.
inline void check_all_parameter_gradients(const Objective& J, const Run& run, unsigned seed = 23)
{
    for (Block b : { Block::REST_POSITIONS, Block::MU, Block::LAMBDA, Block::DENSITY })
        check_parameter_gradient(J, run, b, seed);
}

} // namespace diffipc::test
