// The friction pair kernel (forward/kernels/friction_pair.hpp), which the CPU's FrictionPotential and
// the GPU's DeviceFriction both evaluate: its gradient and Hessian against finite differences of its
// energy in the sticking (|u| < eps) and sliding (|u| > eps) regimes, in 3D and 2D, and its values
// against the closed forms of IPC's mollified speed.

#include "forward/kernels/friction_pair.hpp"
#include "tests/forward/kernels/distance/fd_check.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace diffipc;
using test::Mat;
using test::Vec;

namespace {

/// A pair of nv vertices with random weights, an orthonormal tangent basis (one column in 2D) and
/// mu lambda = scale.
kernels::FrictionPair random_pair(int dim, int nv, unsigned seed)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1, 1);
    kernels::FrictionPair f;
    f.num_vertices = nv;
    for (int i = 0; i < nv; ++i)
        f.weights[i] = u(rng);
    Eigen::Vector3d n(u(rng), u(rng), dim == 3 ? u(rng) : 0.0);
    n.normalize();
    Eigen::Vector3d t0 = dim == 3 ? n.unitOrthogonal() : Eigen::Vector3d(-n.y(), n.x(), 0);
    Eigen::Vector3d t1 = dim == 3 ? n.cross(t0) : Eigen::Vector3d::Zero();
    for (int i = 0; i < 3; ++i) {
        f.tangent[i] = t0[i];
        f.tangent[3 + i] = t1[i];
    }
    f.scale = 2.5;
    return f;
}

template <int N> double energy(int dim, const kernels::FrictionPair& f, const Vec<N>& x, double eps)
{
    kernels::vec3 dx[4];
    for (int i = 0; i < f.num_vertices; ++i)
        dx[i] = kernels::vec3(x[i * dim], x[i * dim + 1], dim == 3 ? x[i * dim + 2] : 0.0);
    return kernels::pair_friction(dim, f, dx, eps, nullptr, nullptr);
}

template <int N> void check(int dim, int nv, double motion, double eps, unsigned seed, const std::string& what)
{
    const kernels::FrictionPair f = random_pair(dim, nv, seed);
    std::mt19937 rng(seed + 100);
    std::uniform_real_distribution<double> u(-1, 1);
    Vec<N> x0;
    for (int k = 0; k < N; ++k)
        x0[k] = motion * u(rng);
    auto to_dx = [&](const Vec<N>& x, kernels::vec3* dx) {
        for (int i = 0; i < nv; ++i)
            dx[i] = kernels::vec3(x[i * dim], x[i * dim + 1], dim == 3 ? x[i * dim + 2] : 0.0);
    };
    auto value = [&](const Vec<N>& x) { return energy<N>(dim, f, x, eps); };
    auto gradient = [&](const Vec<N>& x) {
        kernels::vec3 dx[4];
        to_dx(x, dx);
        Vec<N> g;
        kernels::pair_friction(dim, f, dx, eps, g.data(), nullptr);
        return g;
    };
    auto hessian = [&](const Vec<N>& x) {
        kernels::vec3 dx[4];
        to_dx(x, dx);
        Eigen::Matrix<double, N, N, Eigen::RowMajor> H;
        kernels::pair_friction(dim, f, dx, eps, nullptr, H.data());
        return Mat<N>(H);
    };
    test::FdOptions opt;
    opt.step_scale = eps * 1e-2;
    // In 2D sliding the Hessian vanishes (one tangent, |u| = |u_0|): errors relative to the size
    // the Hessian has elsewhere, mu lambda / |u|.
    opt.floor = f.scale / motion;
    opt.gradient_tolerance = 1e-6;
    opt.hessian_tolerance = 1e-6;
    test::expect_derivatives<N>(value, gradient, hessian, x0, opt, what);
}

} // namespace

TEST(FrictionPair, DerivativesMatchFiniteDifferences3D)
{
    for (unsigned seed = 1; seed <= 3; ++seed) {
        check<12>(3, 4, 1e-4, 1e-3, seed, "3D sticking"); // |u| ~ 1e-4 < eps
        check<12>(3, 4, 1e-1, 1e-3, seed, "3D sliding"); // |u| ~ 1e-1 > eps
    }
}

TEST(FrictionPair, DerivativesMatchFiniteDifferences2D)
{
    for (unsigned seed = 1; seed <= 3; ++seed) {
        check<6>(2, 3, 1e-4, 1e-3, seed, "2D sticking");
        check<6>(2, 3, 1e-1, 1e-3, seed, "2D sliding");
    }
}

TEST(FrictionPair, MollifiedSpeedClosedForms)
{
    const double eps = 1e-3;
    // f0 is the speed itself beyond eps, eps / 3 at rest, and C^2 at eps: just below it
    // f0(eps (1 - d)) = eps (1 - d) + eps d^3 / 3, f1 = 1 - d^2, f1' = 2 d / eps.
    EXPECT_DOUBLE_EQ(kernels::friction_f0(0.5, eps), 0.5);
    EXPECT_DOUBLE_EQ(kernels::friction_f0(0.0, eps), eps / 3);
    EXPECT_NEAR(kernels::friction_f0(eps * (1 - 1e-3), eps), eps * (1 - 1e-3) + eps * 1e-9 / 3, 1e-17);
    EXPECT_NEAR(kernels::friction_f1(eps * (1 - 1e-9), eps), 1.0, 1e-12);
    EXPECT_DOUBLE_EQ(kernels::friction_f1(0.0, eps), 0.0);
    EXPECT_NEAR(kernels::friction_f1_derivative(eps * (1 - 1e-9), eps), 0.0, 1e-5);
    EXPECT_DOUBLE_EQ(kernels::friction_f1_derivative(0.0, eps), 2 / eps);

    // A vertex-plane pair (weights 1, -1) sliding along its first tangent by 0.2: D = mu lambda 0.2,
    // its force mu lambda along that tangent on the vertex, opposite on the plane's point.
    kernels::FrictionPair f;
    f.num_vertices = 2;
    f.weights[0] = 1;
    f.weights[1] = -1;
    f.tangent[0] = 1; // t0 = x, t1 = y
    f.tangent[4] = 1;
    f.scale = 3;
    const kernels::vec3 dx[2] = { kernels::vec3(0.2, 0, 0), kernels::vec3(0, 0, 0) };
    double g[6];
    EXPECT_DOUBLE_EQ(kernels::pair_friction(3, f, dx, eps, g, nullptr), 3 * 0.2);
    EXPECT_DOUBLE_EQ(g[0], 3.0);
    EXPECT_DOUBLE_EQ(g[3], -3.0);
    EXPECT_EQ(g[1], 0.0);
    EXPECT_EQ(g[2], 0.0);
}
