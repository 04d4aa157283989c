// The scalar barrier b(s) and the adaptive stiffness rules (forward/contact/barrier.hpp).

#include "forward/contact/barrier.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

using namespace diffipc;

TEST(Barrier, DerivativesMatchCentralDifferences)
{
    const double shat = 1e-6;
    for (double s : { 1e-12, 1e-10, 3e-9, 1e-8, 1e-7, 5e-7, 9e-7, 0.999e-6 }) {
        const double h = 1e-6 * s;
        const double d1 = (barrier(s + h, shat) - barrier(s - h, shat)) / (2 * h);
        const double d2 = (barrier_first_derivative(s + h, shat) - barrier_first_derivative(s - h, shat)) / (2 * h);
        EXPECT_NEAR(d1, barrier_first_derivative(s, shat), 1e-6 * std::abs(barrier_first_derivative(s, shat)) + 1e-18)
            << "s = " << s;
        EXPECT_NEAR(d2, barrier_second_derivative(s, shat), 1e-6 * std::abs(barrier_second_derivative(s, shat)))
            << "s = " << s;
    }
}

TEST(Barrier, ClampedAndC2AtActivation)
{
    const double shat = 4e-6;
    EXPECT_EQ(barrier(shat, shat), 0);
    EXPECT_EQ(barrier(2 * shat, shat), 0);
    EXPECT_EQ(barrier_first_derivative(2 * shat, shat), 0);
    EXPECT_EQ(barrier_second_derivative(2 * shat, shat), 0);
    // Approaching shat from below, value and first two derivatives go to 0 (C2).
    const double s = shat * (1 - 1e-6);
    EXPECT_LT(std::abs(barrier(s, shat)), 1e-22);
    EXPECT_LT(std::abs(barrier_first_derivative(s, shat)), 1e-16);
    EXPECT_LT(std::abs(barrier_second_derivative(s, shat)), 1e-5);
    // Positive, decreasing and convex inside, infinite at and below zero.
    EXPECT_GT(barrier(1e-3 * shat, shat), 0);
    EXPECT_LT(barrier_first_derivative(1e-3 * shat, shat), 0);
    EXPECT_GT(barrier_second_derivative(1e-3 * shat, shat), 0);
    EXPECT_EQ(barrier(0, shat), std::numeric_limits<double>::infinity());
    EXPECT_EQ(barrier(-1e-9, shat), std::numeric_limits<double>::infinity());
}

TEST(Barrier, MinimumDistanceShiftsTheActivation)
{
    // Active exactly for dmin < d < dmin + dhat.
    const double dhat = 1e-3, dmin = 2e-3;
    const double shat = barrier_activation(dhat, dmin);
    auto b = [&](double d) { return barrier(d * d - dmin * dmin, shat); };
    EXPECT_EQ(b(dmin + dhat), 0);
    EXPECT_GT(b(dmin + 0.999 * dhat), 0);
    EXPECT_EQ(b(dmin), std::numeric_limits<double>::infinity());
}

TEST(Barrier, AdaptiveStiffnessRules)
{
    const double L = 1.0, m = 0.01, dhat = 1e-3;
    const double kmin = barrier_stiffness_min(L, m, dhat, 0);
    EXPECT_GT(kmin, 0);
    EXPECT_TRUE(std::isfinite(kmin));
    // Proportional to the reference mass.
    EXPECT_NEAR(barrier_stiffness_min(L, 2 * m, dhat, 0) / kmin, 2.0, 1e-12);
    // Balancing rule: -(gB . gE) / |gB|^2 clamped to [kmin, 100 kmin]; kmin without a barrier gradient.
    EXPECT_EQ(initial_barrier_stiffness(-5 * kmin, 1.0, kmin), 5 * kmin);
    EXPECT_EQ(initial_barrier_stiffness(+5 * kmin, 1.0, kmin), kmin);
    EXPECT_EQ(initial_barrier_stiffness(-1e4 * kmin, 1.0, kmin), 100 * kmin);
    EXPECT_EQ(initial_barrier_stiffness(-5 * kmin, 0.0, kmin), kmin);
    // Doubling only when both gaps are tiny and decreasing, capped at kappa_max.
    const double eps = std::pow(1e-9 * L, 2);
    EXPECT_EQ(update_barrier_stiffness(0.5 * eps, 0.25 * eps, 3.0, 100.0, L, 0), 6.0);
    EXPECT_EQ(update_barrier_stiffness(0.25 * eps, 0.5 * eps, 3.0, 100.0, L, 0), 3.0);
    EXPECT_EQ(update_barrier_stiffness(2 * eps, 0.5 * eps, 3.0, 100.0, L, 0), 3.0);
    EXPECT_EQ(update_barrier_stiffness(0.5 * eps, 0.25 * eps, 80.0, 100.0, L, 0), 100.0);
}
