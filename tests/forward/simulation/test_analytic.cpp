// Analytic checks of the forward solver: free fall against the closed-form
// discrete solution, the patch test, and a bar under uniaxial load against the
// closed-form homogeneous solution of each material (formulas written out here,
// independently of the material code).

#include "tests/forward/test_utils.hpp"

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>

using namespace diffipc;
using nlohmann::json;

namespace {

TEST(FreeFall, ImplicitEulerMatchesClosedFormDiscreteSolution)
{
    for (int dim : { 2, 3 }) {
        json s = dim == 3 ? test::box_scene(3, { 0.5, 0.2, 0.3 }, { 3, 2, 2 })
                          : test::box_scene(2, { 0.5, 0.2 }, { 4, 2 });
        const Eigen::Vector3d g(0.3, -9.81, 0.7), v0(1.5, 2.0, -0.5);
        s["gravity"] = std::vector<double>(g.data(), g.data() + dim);
        s["bodies"][0]["initial_velocity"] = std::vector<double>(v0.data(), v0.data() + dim);
        const double h = 0.02;
        const int steps = 25;
        s["time"] = { { "integrator", "implicit_euler" }, { "dt", h }, { "steps", steps } };
        Simulator sim(test::make_scene(s));
        sim.run();
        ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED);
        const VectorXd X = flatten(sim.mesh().rest_positions);
        for (const StepRecord& r : sim.trajectory().steps) {
            // v_n = v0 + n h g;  x_n = X + n h v0 + h^2 g n (n + 1) / 2
            const int n = r.index;
            VectorXd expected = X, expected_v(X.size());
            for (Index i = 0; i < X.size(); ++i) {
                expected[i] += n * h * v0[i % dim] + h * h * g[i % dim] * n * (n + 1) / 2.0;
                expected_v[i] = v0[i % dim] + n * h * g[i % dim];
            }
            const double scale = (expected - X).lpNorm<Eigen::Infinity>();
            EXPECT_LT((r.positions - expected).lpNorm<Eigen::Infinity>(), 1e-9 * scale)
                << "dim " << dim << " step " << n;
            EXPECT_LT(
                (r.velocities - expected_v).lpNorm<Eigen::Infinity>(), 1e-9 * expected_v.lpNorm<Eigen::Infinity>());
        }
    }
}

TEST(FreeFall, NewmarkIsExactForConstantAcceleration)
{
    json s = test::box_scene(3, { 0.5, 0.2, 0.3 }, { 2, 2, 2 }, "stvk");
    s["gravity"] = { 0.0, -9.81, 1.0 };
    s["bodies"][0]["initial_velocity"] = { 3.0, 1.0, 0.0 };
    const double h = 0.05;
    s["time"] = { { "integrator", "newmark" }, { "dt", h }, { "steps", 20 } };
    Simulator sim(test::make_scene(s));
    sim.run();
    ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED);
    const VectorXd X = flatten(sim.mesh().rest_positions);
    const Eigen::Vector3d g(0.0, -9.81, 1.0), v0(3.0, 1.0, 0.0);
    for (const StepRecord& r : sim.trajectory().steps) {
        VectorXd expected = X;
        for (Index i = 0; i < X.size(); ++i)
            expected[i] += v0[i % 3] * r.time + 0.5 * g[i % 3] * r.time * r.time;
        EXPECT_LT((r.positions - expected).lpNorm<Eigen::Infinity>(), 1e-9 * (expected - X).lpNorm<Eigen::Infinity>());
        for (Index i = 0; i < X.size(); ++i)
            EXPECT_NEAR(r.accelerations[i], g[i % 3], 1e-6);
    }
}

// Affine Dirichlet data on the whole boundary: the static solution is the same
// affine field everywhere, for every hyperelastic model (no body force).
TEST(PatchTest, AffineBoundaryDisplacementGivesExactAffineField)
{
    for (const char* model : { "linear", "stvk", "neo_hookean", "stable_neo_hookean" })
        for (int dim : { 2, 3 }) {
            json s = dim == 3 ? test::box_scene(3, { 1, 1, 1 }, { 3, 3, 3 }, model, 1e6, 0.3)
                              : test::box_scene(2, { 1, 1 }, { 4, 4 }, model, 1e6, 0.3);
            const Eigen::Matrix3d A
                = (Eigen::Matrix3d() << 0.08, -0.03, 0.02, 0.05, -0.06, 0.01, -0.02, 0.04, 0.07).finished();
            const Eigen::Vector3d b(0.01, -0.02, 0.03);
            json disp = json::array();
            const char* coords[3] = { "x", "y", "z" };
            for (int i = 0; i < dim; ++i) {
                std::string e = std::to_string(b[i]);
                for (int j = 0; j < dim; ++j)
                    e += " + (" + std::to_string(A(i, j)) + ")*" + coords[j];
                disp.push_back(e);
            }
            s["dirichlet"] = json::array();
            for (int axis = 0; axis < dim; ++axis)
                for (double side : { 0.0, 1.0 }) {
                    std::vector<double> lo(static_cast<size_t>(dim), -1.0), hi(static_cast<size_t>(dim), 2.0);
                    lo[size_t(axis)] = hi[size_t(axis)] = side;
                    s["dirichlet"].push_back(
                        { { "body", 0 }, { "region", test::region(lo, hi) }, { "displacement", disp } });
                }
            s["time"] = { { "integrator", "static" }, { "dt", 1.0 }, { "steps", 1 } };
            Simulator sim(test::make_scene(s));
            sim.run();
            ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << model << " " << dim;
            const VectorXd& x = sim.trajectory().steps.back().positions;
            const Positions& X = sim.mesh().rest_positions;
            double worst = 0;
            for (Index v = 0; v < X.rows(); ++v)
                for (int i = 0; i < dim; ++i) {
                    // The expressions were printed with 6 decimals: use the same rounded values.
                    double expected = X(v, i) + std::stod(std::to_string(b[i]));
                    for (int j = 0; j < dim; ++j)
                        expected += std::stod(std::to_string(A(i, j))) * X(v, j);
                    worst = std::max(worst, std::abs(x[v * dim + i] - expected));
                }
            EXPECT_LT(worst, 1e-9) << model << " " << dim << "D";
        }
}

/// Solves f(a, b) = 0 (two equations) by Newton with a central-difference Jacobian.
Eigen::Vector2d solve2(const std::function<Eigen::Vector2d(const Eigen::Vector2d&)>& f, Eigen::Vector2d z)
{
    for (int it = 0; it < 100; ++it) {
        const Eigen::Vector2d r = f(z);
        if (r.norm() < 1e-13)
            break;
        Eigen::Matrix2d J;
        for (int k = 0; k < 2; ++k) {
            Eigen::Vector2d dz = Eigen::Vector2d::Zero();
            dz[k] = 1e-7;
            J.col(k) = (f(z + dz) - f(z - dz)) / 2e-7;
        }
        z -= J.partialPivLu().solve(r);
    }
    return z;
}

/// Principal stretches (a along the load, b lateral) of a bar under nominal
/// traction T, from each model's uniaxial stress equations P11 = T, P22 = 0.
Eigen::Vector2d uniaxial_stretches(const std::string& model, int dim, double E, double nu, double T)
{
    const double mu = E / (2 * (1 + nu)), lambda = E * nu / ((1 + nu) * (1 - 2 * nu));
    const int lat = dim - 1; // number of lateral directions
    auto J = [&](const Eigen::Vector2d& z) { return z[0] * std::pow(z[1], lat); };
    std::function<Eigen::Vector2d(const Eigen::Vector2d&)> f;
    if (model == "linear") {
        // P = 2 mu eps + lambda tr(eps) I with eps = diag(a - 1, b - 1, ...)
        f = [&](const Eigen::Vector2d& z) {
            const double e1 = z[0] - 1, e2 = z[1] - 1, tr = e1 + lat * e2;
            return Eigen::Vector2d(2 * mu * e1 + lambda * tr - T, 2 * mu * e2 + lambda * tr);
        };
    } else if (model == "stvk") {
        // S = 2 mu E + lambda tr(E) I, P = F S, E = (F^2 - I)/2
        f = [&](const Eigen::Vector2d& z) {
            const double E1 = (z[0] * z[0] - 1) / 2, E2 = (z[1] * z[1] - 1) / 2, tr = E1 + lat * E2;
            return Eigen::Vector2d(z[0] * (2 * mu * E1 + lambda * tr) - T, z[1] * (2 * mu * E2 + lambda * tr));
        };
    } else if (model == "neo_hookean") {
        // P = mu (F - F^-T) + lambda ln J F^-T
        f = [&](const Eigen::Vector2d& z) {
            const double l = std::log(J(z));
            return Eigen::Vector2d(
                mu * (z[0] - 1 / z[0]) + lambda * l / z[0] - T, mu * (z[1] - 1 / z[1]) + lambda * l / z[1]);
        };
    } else {
        // P = mu F + (lambda' (J - 1) - mu) cof F, lambda' = lambda + mu; cof diag = J / stretch
        f = [&](const Eigen::Vector2d& z) {
            const double lp = lambda + mu, j = J(z), c = lp * (j - 1) - mu;
            return Eigen::Vector2d(mu * z[0] + c * j / z[0] - T, mu * z[1] + c * j / z[1]);
        };
    }
    return solve2(f, Eigen::Vector2d(1 + T / E, 1 - nu * T / E));
}

TEST(UniaxialBar, MatchesClosedFormForEveryMaterial)
{
    const double E = 1e6, nu = 0.3, T = 2e5; // 20% nominal strain in the linear model
    for (const char* model : { "linear", "stvk", "neo_hookean", "stable_neo_hookean" })
        for (int dim : { 2, 3 }) {
            const double L = 2.0, W = 0.5;
            json s = dim == 3 ? test::box_scene(3, { L, W, W }, { 4, 1, 1 }, model, E, nu)
                              : test::box_scene(2, { L, W }, { 4, 2 }, model, E, nu);
            std::vector<double> lo(size_t(dim), -1.0), hi(size_t(dim), 5.0), pin(size_t(dim), 0.0);
            lo[0] = hi[0] = 0.0;
            json roller = json::array(), pinned = json::array(), no_spin = json::array();
            roller.push_back(0);
            pinned.push_back(nullptr);
            no_spin.push_back(nullptr);
            for (int a = 1; a < dim; ++a) {
                roller.push_back(nullptr);
                pinned.push_back(0);
                no_spin.push_back(a == 2 ? json(0) : json(nullptr));
            }
            s["dirichlet"] = { { { "body", 0 }, { "region", test::region(lo, hi) }, { "displacement", roller } },
                { { "body", 0 }, { "region", test::region(pin, pin) }, { "displacement", pinned } } };
            if (dim == 3) {
                std::vector<double> corner { 0.0, W, 0.0 };
                s["dirichlet"].push_back(
                    { { "body", 0 }, { "region", test::region(corner, corner) }, { "displacement", no_spin } });
            }
            std::vector<double> end_lo(size_t(dim), -1.0), end_hi(size_t(dim), 5.0);
            end_lo[0] = end_hi[0] = L;
            json traction = json::array();
            traction.push_back(std::to_string(T) + "*t/3");
            for (int a = 1; a < dim; ++a)
                traction.push_back(0);
            s["neumann"] = { { { "body", 0 }, { "region", test::region(end_lo, end_hi) }, { "traction", traction } } };
            s["time"] = { { "integrator", "static" }, { "dt", 1.0 }, { "steps", 3 } };
            Simulator sim(test::make_scene(s));
            sim.run();
            ASSERT_EQ(sim.trajectory().final_status, StepStatus::CONVERGED) << model << " " << dim;
            const Eigen::Vector2d ab = uniaxial_stretches(model, dim, E, nu, T);
            const VectorXd& x = sim.trajectory().steps.back().positions;
            const Positions& X = sim.mesh().rest_positions;
            double worst = 0;
            for (Index v = 0; v < X.rows(); ++v) {
                worst = std::max(worst, std::abs(x[v * dim] - ab[0] * X(v, 0)));
                for (int a = 1; a < dim; ++a)
                    worst = std::max(worst, std::abs(x[v * dim + a] - ab[1] * X(v, a)));
            }
            EXPECT_LT(worst, 1e-8 * L) << model << " " << dim << "D, stretches " << ab.transpose();
        }
}

} // namespace
