// The inversion bound kernel (forward/kernels/inversion_bound.hpp), which the CPU's
// inversion_free_step and the GPU's line search both take the minimum of: its volume polynomial
// against determinants computed independently (Eigen) along the step, and its step bound against
// dense sampling of those determinants: the element keeps more than `keep` of its volume on [0, t],
// and t is the first crossing (or 1).

#include "forward/kernels/inversion_bound.hpp"

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

using namespace diffipc;

namespace {

/// dim! times the signed volume of the element xe + t pe, by Eigen's determinant of its edge matrix.
template <int dim> double scaled_volume(const double* xe, const double* pe, double t)
{
    Eigen::Matrix<double, dim, dim> D;
    for (int a = 0; a < dim; ++a)
        for (int i = 0; i < dim; ++i)
            D(i, a) = (xe[(a + 1) * dim + i] + t * pe[(a + 1) * dim + i]) - (xe[i] + t * pe[i]);
    return D.determinant();
}

template <int dim> void random_element(std::mt19937& rng, double step, double* xe, double* pe)
{
    std::uniform_real_distribution<double> u(-1, 1);
    for (int a = 0; a <= dim; ++a)
        for (int i = 0; i < dim; ++i) {
            xe[a * dim + i] = (a > 0 && a - 1 == i ? 1.0 : 0.0) + 0.2 * u(rng); // near the unit simplex
            pe[a * dim + i] = step * u(rng);
        }
}

template <int dim> void check_element(const double* xe, const double* pe, double keep, const std::string& what)
{
    SCOPED_TRACE(what);
    double c[4];
    kernels::volume_polynomial<dim>(xe, pe, c);
    for (double t : { 0.0, 0.3, 0.7, 1.0, 1.6 }) {
        const double exact = scaled_volume<dim>(xe, pe, t);
        EXPECT_NEAR(kernels::eval_cubic(c, t), exact, 1e-12 * (1 + std::abs(exact))) << "t = " << t;
    }
    const double v0 = scaled_volume<dim>(xe, pe, 0);
    const double t = kernels::element_step_bound<dim>(xe, pe, keep);
    if (!(v0 > 0)) {
        EXPECT_EQ(t, 0.0);
        return;
    }
    ASSERT_GT(t, 0.0);
    ASSERT_LE(t, 1.0);
    // Rounding of the two determinants' evaluations: a few ulps of the largest product they sum.
    double m = 0;
    for (int k = 0; k < (dim + 1) * dim; ++k)
        m = std::max({ m, std::abs(xe[k]), std::abs(pe[k]) });
    const double rounding = 1e-13 * std::pow(2 * m, dim);
    for (int k = 0; k <= 2000; ++k) { // the volume stays above keep v0 on [0, t]
        const double s = t * k / 2000.0;
        EXPECT_GT(scaled_volume<dim>(xe, pe, s), keep * v0 - rounding) << "s = " << s << ", t = " << t;
    }
    if (t < 1) // and t is the first crossing: the volume reaches keep v0 just after it
        EXPECT_LE(scaled_volume<dim>(xe, pe, std::min(1.0, t + 1e-9)), keep * v0 + rounding) << "t = " << t;
}

} // namespace

TEST(InversionBound, RandomElementsAndSteps)
{
    std::mt19937 rng(7);
    for (int k = 0; k < 200; ++k) {
        const double step = k % 4 == 0 ? 0.05 : k % 4 == 1 ? 0.5 : k % 4 == 2 ? 2.0 : 10.0; // small to inverting
        double xe2[6], pe2[6], xe3[12], pe3[12];
        random_element<2>(rng, step, xe2, pe2);
        random_element<3>(rng, step, xe3, pe3);
        for (double keep : { 0.0, 0.1 }) {
            check_element<2>(xe2, pe2, keep, "2D, case " + std::to_string(k));
            check_element<3>(xe3, pe3, keep, "3D, case " + std::to_string(k));
        }
    }
}

TEST(InversionBound, ClosedCases)
{
    // The unit triangle; a step that moves vertex 2 onto the line of the other two at t = 0.5 (its
    // height 1 - 2 t): with keep = 0 the bound is the crossing, 0.5 to bisection accuracy.
    const double xe[6] = { 0, 0, 1, 0, 0, 1 };
    const double collapse[6] = { 0, 0, 0, 0, 0, -2 };
    EXPECT_NEAR(kernels::element_step_bound<2>(xe, collapse, 0.0), 0.5, 1e-12);
    // keep = 0.25: the height must stay above 0.25, crossing at t = 0.375.
    EXPECT_NEAR(kernels::element_step_bound<2>(xe, collapse, 0.25), 0.375, 1e-12);
    // A growing element is never bounded; an inverted one admits no step.
    const double grow[6] = { 0, 0, 1, 0, 0, 1 };
    EXPECT_EQ(kernels::element_step_bound<2>(xe, grow, 0.0), 1.0);
    const double inverted[6] = { 0, 0, 0, 1, 1, 0 };
    EXPECT_EQ(kernels::element_step_bound<2>(inverted, grow, 0.0), 0.0);
}
