// Observed convergence order of each integrator on a smooth problem: a 2D
// neo-Hookean cantilever sagging under gravity from rest. The reference is
// Newmark at a 32 times finer step than the finest measured one.

#include "tests/forward/test_utils.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace diffipc;
using nlohmann::json;

namespace {

VectorXd final_positions(const std::string& integrator, int steps, double T)
{
    // Coarse and soft so that every mode of the mesh is resolved by the time
    // steps measured: the asymptotic regime is reached at affordable steps.
    json s = test::box_scene(2, { 1.0, 0.25 }, { 4, 1 }, "neo_hookean", 2e4, 0.3, 1000);
    s["gravity"] = { 0.0, -9.81 };
    s["dirichlet"]
        = { { { "body", 0 }, { "region", test::region({ -1, -1 }, { 0, 1 }) }, { "displacement", { 0, 0 } } } };
    s["time"] = { { "integrator", integrator }, { "dt", T / steps }, { "steps", steps } };
    s["solver"] = { { "residual_tolerance", 1e-11 } };
    Simulator sim(test::make_scene(s));
    sim.run();
    EXPECT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED)
        << integrator << " " << steps << ": " << sim.trajectory().failure_message;
    return sim.positions();
}

TEST(IntegratorOrder, ObservedOrdersMatchTheSchemes)
{
    const double T = 0.4;
    const VectorXd reference = final_positions("newmark", 5120, T);
    for (const auto& [name, order] : std::vector<std::pair<std::string, double>> {
             { "implicit_euler", 1.0 }, { "bdf2", 2.0 }, { "newmark", 2.0 } }) {
        std::vector<double> errors;
        for (int steps : { 20, 40, 80, 160 })
            errors.push_back((final_positions(name, steps, T) - reference).lpNorm<Eigen::Infinity>());
        for (size_t k = 1; k < errors.size(); ++k) {
            const double observed = std::log2(errors[k - 1] / errors[k]);
            std::printf("%s: steps %d -> %d, error %.3e -> %.3e, observed order %.2f\n", name.c_str(), 20 << (k - 1),
                20 << k, errors[k - 1], errors[k], observed);
            EXPECT_GT(observed, order - 0.15) << name;
            EXPECT_LT(observed, order + 0.3) << name;
        }
    }
}

} // namespace
