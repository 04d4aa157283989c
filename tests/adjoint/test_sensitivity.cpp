#include "adjoint/sensitivity.hpp"
#include "forward/materials/material.hpp"

#include <gtest/gtest.h>

using namespace diffipc;

// dJ/dE and dJ/dnu from the Lame derivatives, against central differences of
// J(E, nu) = a mu(E, nu) + b lambda(E, nu).
TEST(Sensitivity, LameToYoungPoissonMatchesFiniteDifferences)
{
    const double a = 0.7, b = -1.3;
    VectorXd E(3), nu(3), dmu = VectorXd::Constant(3, a), dl = VectorXd::Constant(3, b), dE, dnu;
    E << 1e5, 3e6, 2e9;
    nu << 0.3, -0.2, 0.45;
    lame_to_young_poisson(E, nu, dmu, dl, dE, dnu);
    const auto J = [&](double e, double n) { return a * lame_mu(e, n) + b * lame_lambda(e, n); };
    for (Index i = 0; i < 3; ++i) {
        const double he = 1e-6 * E[i], hn = 1e-6;
        const double fe = (J(E[i] + he, nu[i]) - J(E[i] - he, nu[i])) / (2 * he);
        const double fn = (J(E[i], nu[i] + hn) - J(E[i], nu[i] - hn)) / (2 * hn);
        EXPECT_NEAR(dE[i], fe, 1e-7 * std::abs(fe) + 1e-12);
        EXPECT_NEAR(dnu[i], fn, 1e-6 * std::abs(fn));
    }
}

TEST(Sensitivity, AccumulateGrowsEmptyBlocks)
{
    ParameterGradient g, h;
    h.density = VectorXd::Ones(4);
    g.add(h, 2.0);
    g.add(h, 1.0);
    ASSERT_EQ(g.density.size(), 4);
    EXPECT_DOUBLE_EQ(g.density[2], 3.0);
    EXPECT_EQ(g.mu.size(), 0);
}
