#pragma once
// Finite-difference checks of a ParameterMap's vector-Jacobian product, shared by the
// parametrization tests: central differences along random directions with fixed seeds.

#include "shape_opt/parametrization/parameter_map.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace diffipc::test {

/// Checks y_bar . (m(x + h d) - m(x - h d)) / 2h against vjp(x, y_bar) . d for `directions`
/// random d and y_bar (entries uniform in [-1, 1], d scaled by `scale`), seed `seed`.
/// The central difference's error is O(h^2) with the third derivative, plus round-off
/// eps |y| / h; `tolerance` is relative to the larger of the two products and |y_bar| |dy/dh|.
inline void expect_vjp_matches_differences(const ParameterMap& map, const VectorXd& x, double h = 1e-6,
    double tolerance = 1e-7, int directions = 4, unsigned seed = 1, double scale = 1.0)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int k = 0; k < directions; ++k) {
        VectorXd d(map.in_size()), y_bar(map.out_size());
        for (Index i = 0; i < d.size(); ++i)
            d[i] = scale * u(rng);
        for (Index i = 0; i < y_bar.size(); ++i)
            y_bar[i] = u(rng);
        const VectorXd plus = map.apply(x + h * d), minus = map.apply(x - h * d);
        const double fd = y_bar.dot(plus - minus) / (2 * h);
        const double exact = map.vjp(x, y_bar).dot(d);
        const double size = std::max({ std::abs(fd), std::abs(exact),
            y_bar.cwiseAbs().dot((plus - minus).cwiseAbs()) / (2 * h), 1e-300 });
        EXPECT_LE(std::abs(fd - exact), tolerance * size)
            << map.name() << " direction " << k << ": vjp " << exact << ", difference " << fd;
    }
}

} // namespace diffipc::test
