// The PSD projections the two paths use, timed against each other on one thread:
//
//   ./build/bench/bench_psd_projection [samples]
//
// 1. dP/dF of an element (9 x 9 in 3D, 4 x 4 in 2D): Eigen's LLT test and SelfAdjointEigenSolver
//    (project_psd, forward/materials/material.cpp) against the closed-form eigensystems that the GPU's
//    element Hessians use (kernels::project_stress_derivative, forward/kernels/material/eigensystem.hpp),
//    on random deformation gradients (|F - I| entries up to 0.4, inverted ones replaced).
// 2. A small symmetric matrix with one negative eigenvalue (a contact pair's Hessian: 6 x 6 in 2D, up to
//    12 x 12 in 3D): Eigen's solver, which the CPU's contact uses,
//    against the cyclic Jacobi of kernels::project_psd, which the GPU's contact uses.
// Prints the mean time per matrix of each, their ratio, and the largest relative difference of the
// two projections (Frobenius). Asserts nothing.

#include "forward/kernels/material/eigensystem.hpp"
#include "forward/kernels/project_psd.hpp"
#include "forward/materials/material.hpp"

#include <Eigen/Dense>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

using namespace diffipc;

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) { return std::chrono::duration<double>(Clock::now() - start).count(); }

template <int dim> void elastic_projection(MaterialModel model, int samples)
{
    constexpr int n = dim * dim;
    using RowMat = Eigen::Matrix<double, n, n, Eigen::RowMajor>;
    std::mt19937 rng(11 + dim);
    std::uniform_real_distribution<double> u(-0.4, 0.4);
    std::vector<RowMat> A(static_cast<size_t>(samples));
    std::vector<std::array<double, n>> F(static_cast<size_t>(samples));
    const double mu = 1.0, lambda = 4.0;
    for (int k = 0; k < samples; ++k) {
        for (int i = 0; i < n; ++i)
            F[size_t(k)][size_t(i)] = (i % (dim + 1) == 0 ? 0.8 : 0.0) + u(rng);
        if (!(kernels::determinant<dim>(F[size_t(k)].data()) > 0))
            for (int i = 0; i < n; ++i)
                F[size_t(k)][size_t(i)] = i % (dim + 1) == 0 ? 0.7 : 0.0;
        kernels::stress_derivative<dim>(model, F[size_t(k)].data(), mu, lambda, A[size_t(k)].data());
    }
    std::vector<Eigen::Matrix<double, n, n>> eigen(static_cast<size_t>(samples));
    std::vector<RowMat> closed = A;
    Clock::time_point start = Clock::now();
    for (int k = 0; k < samples; ++k)
        eigen[size_t(k)] = project_psd<n>(Eigen::Matrix<double, n, n>(A[size_t(k)]));
    const double t_eigen = seconds_since(start);
    start = Clock::now();
    int changed = 0;
    for (int k = 0; k < samples; ++k)
        changed += kernels::project_stress_derivative<dim>(
            model, F[size_t(k)].data(), mu, lambda, closed[size_t(k)].data());
    const double t_closed = seconds_since(start);
    double worst = 0;
    for (int k = 0; k < samples; ++k)
        worst = std::max(
            worst, (Eigen::Matrix<double, n, n>(closed[size_t(k)]) - eigen[size_t(k)]).norm() / A[size_t(k)].norm());
    std::printf("  dP/dF %dD %-20s Eigen %7.3f us  closed form %7.3f us  Eigen/closed %5.2f  projected %5.1f%%  "
                "max rel diff %.1e\n",
        dim, to_string(model).c_str(), 1e6 * t_eigen / samples, 1e6 * t_closed / samples, t_eigen / t_closed,
        100.0 * changed / samples, worst);
}

template <int n> void pair_projection(int samples)
{
    using Mat = Eigen::Matrix<double, n, n>;
    std::mt19937 rng(5 + n);
    std::uniform_real_distribution<double> u(-1, 1);
    std::vector<Mat> A(static_cast<size_t>(samples));
    for (Mat& a : A) {
        Mat R;
        for (int i = 0; i < n * n; ++i)
            R.data()[i] = u(rng);
        const Mat Q = Eigen::HouseholderQR<Mat>(R).householderQ();
        Eigen::Matrix<double, n, 1> d;
        for (int i = 0; i < n; ++i)
            d[i] = i == 0 ? -1e-3 : std::pow(10.0, 3 * u(rng)); // one negative, the rest spread over 6 decades
        a = Q * d.asDiagonal() * Q.transpose();
    }
    std::vector<Mat> eigen(static_cast<size_t>(samples));
    std::vector<Eigen::Matrix<double, n, n, Eigen::RowMajor>> jacobi(A.begin(), A.end());
    Clock::time_point start = Clock::now();
    for (int k = 0; k < samples; ++k)
        eigen[size_t(k)] = project_psd<n>(A[size_t(k)]);
    const double t_eigen = seconds_since(start);
    start = Clock::now();
    for (int k = 0; k < samples; ++k)
        kernels::project_psd<n>(jacobi[size_t(k)].data());
    const double t_jacobi = seconds_since(start);
    double worst = 0;
    for (int k = 0; k < samples; ++k)
        worst = std::max(worst, (Mat(jacobi[size_t(k)]) - eigen[size_t(k)]).norm() / A[size_t(k)].norm());
    std::printf("  %2d x %-2d indefinite          Eigen %7.3f us  Jacobi      %7.3f us  Jacobi/Eigen %5.2f  "
                "max rel diff %.1e\n",
        n, n, 1e6 * t_eigen / samples, 1e6 * t_jacobi / samples, t_jacobi / t_eigen, worst);
}

} // namespace

int main(int argc, char** argv)
{
    const int samples = argc > 1 ? std::atoi(argv[1]) : 20000;
    if (samples < 1) {
        std::fprintf(stderr, "bench_psd_projection: samples must be a positive integer\n");
        return 2;
    }
    std::printf("PSD projection, %d matrices each, one thread\n", samples);
    std::printf("element dP/dF (CPU: Eigen, GPU: closed form):\n");
    for (MaterialModel model : { MaterialModel::STVK, MaterialModel::NEO_HOOKEAN, MaterialModel::STABLE_NEO_HOOKEAN }) {
        elastic_projection<2>(model, samples);
        elastic_projection<3>(model, samples);
    }
    std::printf("contact pair Hessians (CPU: Eigen, GPU: Jacobi):\n");
    pair_projection<6>(samples);
    pair_projection<9>(samples);
    pair_projection<12>(samples);
    return 0;
}
