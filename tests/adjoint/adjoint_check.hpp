#pragma once
// Finite-difference checks of adjoint gradients: central differences in a
// random direction per parameter block and a Taylor test (remainder rates),
// every forward run built from SimulationParameters.

#include "adjoint/adjoint.hpp"
#include "adjoint/parameter_blocks.hpp"
#include "forward/test_utils.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace diffipc::test {

/// A soft box over a plane obstacle rising at 0.01 m/s (its point is a prescribed dof),
/// contact with dhat and a fixed kappa = 1e3, forward tolerance 1e-11; the callers
/// place the box and add what their case needs.
inline nlohmann::json box_over_rising_plane(int dim, const std::string& integrator, double dhat, double dt, int steps)
{
    using json = nlohmann::json;
    json s = dim == 2 ? box_scene(2, { 0.2, 0.1 }, { 4, 2 }, "neo_hookean", 2e4, 0.3, 1000)
                      : box_scene(3, { 0.2, 0.1, 0.2 }, { 2, 1, 2 }, "neo_hookean", 2e4, 0.3, 1000);
    s["gravity"] = dim == 2 ? json { 0, -9.81 } : json { 0, -9.81, 0 };
    json plane = { { "point", dim == 2 ? json { 0, 0 } : json { 0, 0, 0 } },
        { "normal", dim == 2 ? json { 0, 1 } : json { 0, 1, 0 } },
        { "motion", dim == 2 ? json { 0, "0.01*t" } : json { 0, "0.01*t", 0 } } };
    s["obstacles"] = { { { "name", "floor" }, { "plane", plane } } };
    s["contact"] = { { "dhat", dhat }, { "kappa", 1e3 } };
    s["time"] = { { "integrator", integrator }, { "dt", dt }, { "steps", steps } };
    s["solver"] = { { "residual_tolerance", 1e-11 } };
    return s;
}

/// J = sum_k a_k . (x_k - X) + b_k . v_k + c/2 |x_T - X|^2 with fixed random a_k, b_k: every
/// state of the run is seeded, so every backward path of the adjoint is exercised.
struct StateObjective {
    std::vector<VectorXd> a, b;
    double c = 1.0;

    StateObjective(int steps, Index n, double length, double dt, unsigned seed)
    {
        for (int k = 0; k <= steps; ++k) {
            a.push_back(random_vector(n, seed + 2 * unsigned(k)) / length);
            b.push_back(random_vector(n, seed + 2 * unsigned(k) + 1) * dt / length);
        }
        c = 1.0 / (length * length);
    }
    static const VectorXd& x(const Trajectory& tr, int k)
    {
        return k == 0 ? tr.initial_positions : tr.steps[size_t(k - 1)].positions;
    }
    static const VectorXd& v(const Trajectory& tr, int k)
    {
        return k == 0 ? tr.initial_velocities : tr.steps[size_t(k - 1)].velocities;
    }
    double value(const Simulator& sim) const
    {
        const Trajectory& tr = sim.trajectory();
        const int T = int(tr.steps.size());
        const VectorXd X = flatten(sim.mesh().rest_positions);
        double J = 0;
        for (int k = 0; k <= T; ++k)
            J += a[size_t(k)].dot(x(tr, k) - X) + b[size_t(k)].dot(v(tr, k));
        const VectorXd u = x(tr, T) - X;
        return J + 0.5 * c * u.squaredNorm();
    }
    StateSeed seed(const Simulator& sim) const
    {
        const Trajectory& tr = sim.trajectory();
        const int T = int(tr.steps.size());
        StateSeed s;
        s.resize(T);
        VectorXd sum_a = VectorXd::Zero(a[0].size());
        for (int k = 0; k <= T; ++k) {
            s.add_position(k, a[size_t(k)]);
            s.add_velocity(k, b[size_t(k)]);
            sum_a += a[size_t(k)];
        }
        const VectorXd u = x(tr, T) - flatten(sim.mesh().rest_positions);
        s.add_position(T, c * u);
        s.explicit_partials.rest_positions = -c * u - sum_a;
        return s;
    }
};

struct CheckSettings {
    double tolerance = 1e-6; ///< relative error of the central difference
    double min_rate = 1.9; ///< Taylor second-order remainder rate
    unsigned seed = 7;
    /// Central-difference step (times the block's direction). Contact scenes need a
    /// smaller one: the barrier's derivatives grow like 1/d^k near contact, and so
    /// does the difference quotient's truncation error.
    double fd_step = 1e-2;
    /// First Taylor step; halved six times.
    double taylor_step = 0.1;
};

/// @brief Taylor test of a directional derivative `exact` of J at h = 0: |J(h) - J(0) - h exact|
/// = O(h^2), over h = first_step halved six times. The rate is read where it has converged (the
/// last halvings): at the first ones the cubic term can still compete (density enters as 1/rho
/// through the inertia). Remainders below the forward solves' resolution (1e-10 |J|, their
/// residual tolerance is 1e-11) carry no information; at least three must lie above it.
inline void expect_taylor_rate(
    const std::function<double(double)>& Jh, double J0, double exact, double first_step, double min_rate)
{
    std::vector<double> remainder;
    std::string table;
    for (double h = first_step; h > first_step / 64 * 0.99; h /= 2) {
        remainder.push_back(std::abs(Jh(h) - J0 - h * exact));
        char line[96];
        std::snprintf(line, sizeof line, "  h %.5g  remainder %.4e\n", h, remainder.back());
        table += line;
    }
    const double floor = 1e-10 * std::abs(J0);
    size_t m = 0;
    while (m < remainder.size() && remainder[m] > floor)
        ++m;
    ASSERT_GE(m, 3u) << "the Taylor test cannot resolve this block: start from a larger step\n" << table;
    const double last_rate = std::log2(remainder[m - 2] / remainder[m - 1]);
    EXPECT_GE(last_rate, min_rate) << table;
    for (size_t i = 1; i < m; ++i)
        EXPECT_LT(remainder[i], remainder[i - 1]) << table;
}

/// @brief Runs the scene, the adjoint for `blocks`, and checks each block in a
/// random direction against central differences and by a Taylor test.
/// @param kappa fixed barrier stiffness for contact scenes (0: none)
/// @param substeps SimulationParameters::substeps of the nominal run (dynamic sub-steps given)
inline void check_adjoint(const nlohmann::json& scene_json, const std::vector<Block>& blocks,
    const CheckSettings& settings = {}, double kappa = 0, const std::vector<std::vector<double>>& substeps = {})
{
    const Scene scene = make_scene(scene_json);
    SimulationParameters nominal;
    nominal.kappa = kappa;
    nominal.substeps = substeps;
    Simulator sim(scene, nominal);
    sim.run();
    ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << sim.trajectory().failure_message;
    const SimulationParameters base = sim.parameters();
    const Index n = sim.mesh().num_dofs();
    const double length = sim.bbox_diagonal();
    const int T = sim.steps_done();
    const StateObjective objective(T, n, length, scene.time.dt, settings.seed);

    const ParameterRequest request = request_for(blocks);
    const ParameterGradient grad = adjoint_gradient(sim, objective.seed(sim), request);
    const double J0 = objective.value(sim);

    const auto J = [&](const SimulationParameters& p) {
        Simulator s(scene, p);
        s.run();
        EXPECT_EQ(s.trajectory().final_status, StepStatus::CONVERGED) << s.trajectory().failure_message;
        return objective.value(s);
    };

    unsigned seed = settings.seed * 101;
    for (Block b : blocks) {
        SCOPED_TRACE(block_name(b));
        // Directions scaled to the block: lengths for positions, relative for moduli and densities.
        VectorXd dir;
        MatrixXd dir_matrix;
        const double eps = settings.fd_step;
        switch (b) {
        case Block::REST_POSITIONS:
            dir = keep_pairing(sim, random_vector(n, ++seed) * 1e-2 * length);
            break;
        case Block::INITIAL_DISPLACEMENT:
            dir = random_vector(n, ++seed) * 1e-2 * length;
            break;
        case Block::INITIAL_VELOCITY:
            dir = random_vector(n, ++seed) * 1e-1;
            break;
        case Block::MU:
            dir = random_vector(base.mu.size(), ++seed).cwiseProduct(base.mu);
            break;
        case Block::LAMBDA:
            dir = random_vector(base.lambda.size(), ++seed).cwiseProduct(base.lambda);
            break;
        case Block::DENSITY:
            dir = random_vector(base.density.size(), ++seed).cwiseProduct(base.density);
            break;
        case Block::FRICTION:
            dir = random_vector(base.friction.size(), ++seed).cwiseProduct(base.friction);
            break;
        case Block::MACRO:
            ASSERT_GT(base.macro_gradient.size(), 0) << "the scene is not a periodic cell";
            {
                // Relative to the largest prescribed value (G is dimensionless).
                const VectorXd r = random_vector(base.macro_gradient.size(), ++seed)
                    * std::max(1e-3, base.macro_gradient.cwiseAbs().maxCoeff());
                dir_matrix
                    = Eigen::Map<const MatrixXd>(r.data(), base.macro_gradient.rows(), base.macro_gradient.cols());
            }
            break;
        case Block::PRESCRIBED:
            ASSERT_GT(base.prescribed.size(), 0) << "the scene has no prescribed dofs";
            dir_matrix = MatrixXd(base.prescribed.rows(), base.prescribed.cols());
            {
                const VectorXd r = random_vector(dir_matrix.size(), ++seed) * 1e-2 * length;
                dir_matrix = Eigen::Map<const MatrixXd>(r.data(), dir_matrix.rows(), dir_matrix.cols());
            }
            break;
        }
        const double exact = block_dot(grad, b, dir, dir_matrix);
        // Fourth-order central difference: truncation O(eps^4) lets eps stay large
        // enough that the forward solves' round-off does not show.
        const auto Jh = [&](double h) { return J(perturbed(base, b, dir, dir_matrix, h)); };
        const double fd = central_difference(Jh, eps);
        EXPECT_NEAR(exact, fd, settings.tolerance * std::abs(fd))
            << "adjoint " << exact << " central difference " << fd << " relative error "
            << std::abs(exact - fd) / std::abs(fd);
        EXPECT_GT(std::abs(fd), 1e-8 * std::abs(J0)) << "the direction does not change J: the check would be empty";

        expect_taylor_rate(Jh, J0, exact, settings.taylor_step, settings.min_rate);
    }
}

} // namespace diffipc::test
