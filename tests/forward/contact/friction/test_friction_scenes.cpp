// Frictional scenes against closed forms: a block on an inclined plane slides
// with a = g (sin theta - mu cos theta) when tan theta > mu and sticks otherwise.
// The incline is modelled by tilting gravity over a horizontal plane.

#include "../../test_utils.hpp"

#include "forward/contact/intersection.hpp"
#include "forward/simulation/simulator.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace diffipc;
using nlohmann::json;

namespace {

constexpr double G = 9.81;

json block_on_incline(int dim, double theta, double mu, double dt, int steps)
{
    json s = test::box_scene(dim, dim == 2 ? std::vector<double> { 0.1, 0.05 } : std::vector<double> { 0.1, 0.05, 0.1 },
        dim == 2 ? std::vector<int> { 4, 2 } : std::vector<int> { 2, 1, 2 }, "neo_hookean", 1e7, 0.3, 1000);
    s["bodies"][0]["translation"] = dim == 2 ? json { 0, 5e-5 } : json { 0, 5e-5, 0 };
    std::vector<double> g(size_t(dim), 0.0), normal(size_t(dim), 0.0), origin(size_t(dim), 0.0);
    g[0] = G * std::sin(theta);
    g[1] = -G * std::cos(theta);
    normal[1] = 1;
    s["gravity"] = g;
    s["obstacles"] = { { { "plane", { { "point", origin }, { "normal", normal } } } } };
    s["contact"] = { { "dhat", 1e-4 } };
    s["friction"] = { { "coefficient", mu }, { "eps_v", 1e-3 }, { "iterations", 10 } };
    s["time"] = { { "integrator", "implicit_euler" }, { "dt", dt }, { "steps", steps } };
    s["solver"] = { { "residual_tolerance", 1e-8 } };
    return s;
}

/// Mass-weighted mean of the body's x velocity (along the slope).
double slope_velocity(const Simulator& sim, const VectorXd& v)
{
    const int d = sim.scene().dim;
    VectorXd density = VectorXd::Constant(sim.mesh().num_elements(), 1000.0);
    const VectorXd m = sim.space().lumped_masses(density);
    double p = 0, total = 0;
    for (Index i = 0; i < sim.scene().body_vertices; ++i) {
        p += m[i] * v[i * d];
        total += m[i];
    }
    return p / total;
}

void check_sliding(int dim, double dt)
{
    const double theta = 30 * M_PI / 180, mu = 0.2;
    const double expected = G * (std::sin(theta) - mu * std::cos(theta));
    const int steps = int(std::round(0.2 / dt));
    Simulator sim(test::make_scene(block_on_incline(dim, theta, mu, dt, steps)));
    std::vector<double> v(size_t(steps) + 1, 0.0);
    for (int k = 1; k <= steps; ++k) {
        ASSERT_EQ(sim.step(), StepStatus::CONVERGED) << sim.trajectory().failure_message;
        v[size_t(k)] = slope_velocity(sim, sim.velocities());
    }
    // After the transient (the normal force builds up in the first steps): the second half.
    const int k0 = steps / 2;
    const double a = (v[size_t(steps)] - v[size_t(k0)]) / ((steps - k0) * dt);
    std::printf("  %dD dt = %g: a = %.5f m/s^2, closed form %.5f, error %.3f%%\n", dim, dt, a, expected,
        100 * std::abs(a / expected - 1));
    EXPECT_LT(std::abs(a / expected - 1), 0.01);
    const Positions X = unflatten(sim.positions(), dim);
    EXPECT_EQ(count_inverted_elements(sim.scene().mesh, X), 0);
}

void check_sticking(int dim, double dt)
{
    const double theta = 30 * M_PI / 180, mu = 0.8; // tan 30 deg = 0.577 < 0.8
    const double eps_v = 1e-3;
    const int steps = int(std::round(0.2 / dt));
    Simulator sim(test::make_scene(block_on_incline(dim, theta, mu, dt, steps)));
    const VectorXd x0 = sim.positions();
    VectorXd x_half;
    for (int k = 1; k <= steps; ++k) {
        ASSERT_EQ(sim.step(), StepStatus::CONVERGED) << sim.trajectory().failure_message;
        if (k == steps / 2)
            x_half = sim.positions();
    }
    // The block starts inside dhat, so the barrier first lifts it a little and it
    // lands again within a few steps (20 at dt = 1e-3); from then on it must stick:
    // a relative speed below eps_v, so over the second half it may move at most
    // eps_v dt (steps / 2).
    double late = 0, total = 0;
    for (Index i = 0; i < sim.scene().body_vertices; ++i) {
        late = std::max(late, std::abs(sim.positions()[i * dim] - x_half[i * dim]));
        total = std::max(total, std::abs(sim.positions()[i * dim] - x0[i * dim]));
    }
    const double bound = eps_v * dt * (steps - steps / 2);
    const double sliding = 0.5 * G * std::sin(theta) * 0.2 * 0.2; // frictionless distance over the run
    std::printf("  %dD dt = %g: drift over the second half %.3e m (bound eps_v dt steps %.3e m); over the run %.3e m "
                "(frictionless %.3e m)\n",
        dim, dt, late, bound, total, sliding);
    EXPECT_LT(late, bound);
    EXPECT_LT(total, 1e-2 * sliding);
}

} // namespace

TEST(FrictionScenes, InclinedPlaneSliding2D)
{
    check_sliding(2, 1e-3);
    check_sliding(2, 1e-2);
}

TEST(FrictionScenes, InclinedPlaneSliding3D)
{
    check_sliding(3, 1e-3);
    check_sliding(3, 1e-2);
}

TEST(FrictionScenes, InclinedPlaneSticking2D)
{
    check_sticking(2, 1e-3);
    check_sticking(2, 1e-2);
}

TEST(FrictionScenes, InclinedPlaneSticking3D)
{
    check_sticking(3, 1e-3);
    check_sticking(3, 1e-2);
}
