// The GPU's __host__ __device__ element functions (cuda/elastic/element.cuh), run here on the
// CPU, against the CPU's materials and element_energy / element_gradient / element_hessian
// (forward/potentials/elastic_potential.hpp). No GPU needed.

#include "cuda/elastic/element.cuh"
#include "forward/materials/material.hpp"
#include "forward/potentials/elastic_potential.hpp"

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

using namespace diffipc;

namespace {

constexpr MaterialModel MODELS[]
    = { MaterialModel::LINEAR, MaterialModel::STVK, MaterialModel::NEO_HOOKEAN, MaterialModel::STABLE_NEO_HOOKEAN };

/// A random element: rest = a unit simplex scaled, sheared and moved; deformed = rest mapped by a
/// random F (near identity, large, near-inverted or inverted) plus a translation.
struct Case {
    MatrixXd rest, deformed;
    double mu, lambda;
    std::string kind;
};

template <int dim> Case random_case(std::mt19937& rng, int which)
{
    std::uniform_real_distribution<double> u(-1, 1);
    Case c;
    c.rest = MatrixXd::Zero(dim + 1, dim);
    for (int a = 1; a <= dim; ++a)
        c.rest(a, a - 1) = 1;
    Eigen::Matrix<double, dim, dim> A = Eigen::Matrix<double, dim, dim>::Identity();
    for (int i = 0; i < dim; ++i)
        for (int j = 0; j < dim; ++j)
            A(i, j) += 0.3 * u(rng);
    Eigen::Matrix<double, 1, dim> shift;
    for (int i = 0; i < dim; ++i)
        shift[i] = u(rng);
    c.rest = ((c.rest * A.transpose()) * (0.5 + 0.5 * std::abs(u(rng)))).rowwise() + shift;

    Eigen::Matrix<double, dim, dim> F = Eigen::Matrix<double, dim, dim>::Identity();
    switch (which % 4) {
    case 0: // moderate
        c.kind = "moderate";
        for (int i = 0; i < dim; ++i)
            for (int j = 0; j < dim; ++j)
                F(i, j) += 0.2 * u(rng);
        break;
    case 1: // large
        c.kind = "large";
        for (int i = 0; i < dim; ++i)
            for (int j = 0; j < dim; ++j)
                F(i, j) += 0.8 * u(rng);
        break;
    case 2: { // near-inverted: one direction squashed to 1e-3 .. 1e-2
        c.kind = "near-inverted";
        for (int i = 0; i < dim; ++i)
            for (int j = 0; j < dim; ++j)
                F(i, j) += 0.1 * u(rng);
        Eigen::Matrix<double, dim, 1> n;
        for (int i = 0; i < dim; ++i)
            n[i] = u(rng);
        n.normalize();
        const double s = std::pow(10.0, -2 - std::abs(u(rng)));
        F = F * (Eigen::Matrix<double, dim, dim>::Identity() - (1 - s) * n * n.transpose());
        break;
    }
    default: { // inverted: a reflection (J < 0)
        c.kind = "inverted";
        for (int i = 0; i < dim; ++i)
            for (int j = 0; j < dim; ++j)
                F(i, j) += 0.2 * u(rng);
        F.col(0) *= -0.5;
        break;
    }
    }
    Eigen::Matrix<double, 1, dim> t;
    for (int i = 0; i < dim; ++i)
        t[i] = u(rng);
    c.deformed = (c.rest * F.transpose()).rowwise() + t;
    c.mu = std::pow(10.0, 3 + 3 * std::abs(u(rng)));
    c.lambda = c.mu * std::pow(10.0, 1.5 * u(rng));
    return c;
}

/// Row-major copy of a (dim+1) by dim matrix.
std::vector<double> rows(const MatrixXd& m)
{
    std::vector<double> out(size_t(m.size()));
    for (Index a = 0; a < m.rows(); ++a)
        for (Index i = 0; i < m.cols(); ++i)
            out[size_t(a * m.cols() + i)] = m(a, i);
    return out;
}

template <int dim> void compare_elements(int count)
{
    constexpr int L = dim * (dim + 1);
    std::mt19937 rng(1234 + dim);
    double worst_energy = 0, worst_gradient = 0, worst_hessian[2] = { 0, 0 };
    for (int k = 0; k < count; ++k) {
        const Case c = random_case<dim>(rng, k);
        const auto rest = rows(c.rest), deformed = rows(c.deformed);
        const double J = (c.deformed.bottomRows(dim).rowwise() - c.deformed.row(0)).determinant()
            / (c.rest.bottomRows(dim).rowwise() - c.rest.row(0)).determinant();
        for (MaterialModel model : MODELS) {
            const MaterialModel gm = model;
            const std::string where = "dim " + std::to_string(dim) + ", " + to_string(model) + ", " + c.kind + " case "
                + std::to_string(k) + ", J " + std::to_string(J);
            const double e_cpu = element_energy(model, c.rest, c.deformed, c.mu, c.lambda);
            const double e_gpu = gpu::element_energy_from_rest<dim>(gm, rest.data(), deformed.data(), c.mu, c.lambda);
            if (model == MaterialModel::NEO_HOOKEAN && !(J > 0)) {
                EXPECT_TRUE(std::isinf(e_cpu) && e_cpu > 0) << where;
                EXPECT_TRUE(std::isinf(e_gpu) && e_gpu > 0) << where;
                continue; // the CPU's gradient and Hessian are not finite there either
            }
            // The neo-Hookean energies cancel terms of size |e| mu d (ElasticPotential::value_scale).
            double volume;
            double G[(dim + 1) * dim];
            gpu::element_rest_data<dim>(rest.data(), G, volume);
            const double energy_scale = std::abs(e_cpu) + volume * c.mu * dim;
            const double de = std::abs(e_gpu - e_cpu) / energy_scale;
            EXPECT_LE(de, 1e-12) << where << ": energy " << e_gpu << " vs " << e_cpu;
            worst_energy = std::max(worst_energy, de);

            const VectorXd g_cpu = element_gradient(model, c.rest, c.deformed, c.mu, c.lambda);
            VectorXd g_gpu(L);
            gpu::element_gradient_from_rest<dim>(gm, rest.data(), deformed.data(), c.mu, c.lambda, g_gpu.data());
            const double dg = (g_gpu - g_cpu).norm() / g_cpu.norm();
            EXPECT_LE(dg, 1e-12) << where << ": gradient";
            worst_gradient = std::max(worst_gradient, dg);

            // Relative to the true Hessian: a projected one may vanish (all of dP/dF negative).
            const double hessian_scale = element_hessian(model, c.rest, c.deformed, c.mu, c.lambda, false).norm();
            for (bool project : { false, true }) {
                const MatrixXd H_cpu = element_hessian(model, c.rest, c.deformed, c.mu, c.lambda, project);
                Eigen::Matrix<double, L, L, Eigen::RowMajor> H_gpu;
                gpu::element_hessian_from_rest<dim>(
                    gm, rest.data(), deformed.data(), c.mu, c.lambda, project, H_gpu.data());
                const double dh = (MatrixXd(H_gpu) - H_cpu).norm() / hessian_scale;
                EXPECT_LE(dh, 1e-12) << where << ": Hessian, project " << project;
                worst_hessian[project] = std::max(worst_hessian[project], dh);
                if (project) {
                    const double min_eig = Eigen::SelfAdjointEigenSolver<MatrixXd>(MatrixXd(H_gpu)).eigenvalues()[0];
                    EXPECT_GE(min_eig, -1e-12 * hessian_scale) << where << ": projected Hessian not PSD";
                }
            }
        }
    }
    std::printf("dim %d, %d cases x 4 models: worst relative differences GPU vs CPU: energy %.2e, gradient %.2e, "
                "Hessian %.2e, projected Hessian %.2e\n",
        dim, count, worst_energy, worst_gradient, worst_hessian[0], worst_hessian[1]);
}

TEST(GpuElement, EnergyGradientHessianEqualCpu2D) { compare_elements<2>(400); }
TEST(GpuElement, EnergyGradientHessianEqualCpu3D) { compare_elements<3>(400); }

template <int dim> void compare_materials()
{
    using Mat = Eigen::Matrix<double, dim, dim, Eigen::RowMajor>;
    constexpr int n = dim * dim;
    std::mt19937 rng(77 + dim);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int k = 0; k < 200; ++k) {
        Mat F = Mat::Identity();
        for (int i = 0; i < n; ++i)
            F.data()[i] += 0.4 * u(rng);
        const double mu = 1 + std::abs(u(rng)), lambda = 3 * std::abs(u(rng));
        for (MaterialModel model : MODELS) {
            if (model == MaterialModel::NEO_HOOKEAN && !(F.determinant() > 0))
                continue;
            const auto m = make_material<dim>(model);
            const MaterialModel gm = model;
            const Eigen::Matrix<double, dim, dim> Fc = F;
            const double psi = m->energy_density(Fc, mu, lambda);
            EXPECT_NEAR(gpu::energy_density<dim>(gm, F.data(), mu, lambda), psi, 1e-13 * (std::abs(psi) + mu * dim));
            Mat P;
            gpu::stress<dim>(gm, F.data(), mu, lambda, P.data());
            const Mat P_cpu = m->stress(Fc, mu, lambda);
            EXPECT_LE((P - P_cpu).norm(), 1e-13 * P_cpu.norm()) << to_string(model);
            Eigen::Matrix<double, n, n, Eigen::RowMajor> A;
            gpu::stress_derivative<dim>(gm, F.data(), mu, lambda, A.data());
            const Eigen::Matrix<double, n, n> A_cpu = m->stress_derivative(Fc, mu, lambda);
            EXPECT_LE((Eigen::Matrix<double, n, n>(A) - A_cpu).norm(), 1e-13 * A_cpu.norm()) << to_string(model);
        }
    }
}

TEST(GpuMaterial, DensityStressAndDerivativeEqualCpu)
{
    compare_materials<2>();
    compare_materials<3>();
}

template <int n> void compare_projection(double spread)
{
    using Mat = Eigen::Matrix<double, n, n, Eigen::RowMajor>;
    std::mt19937 rng(5 + n);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int k = 0; k < 300; ++k) {
        // Eigenvalues from -spread to 1, some repeated, in a random orthogonal basis.
        Eigen::Matrix<double, n, 1> d;
        for (int i = 0; i < n; ++i)
            d[i] = (k % 3 == 0 && i % 2 == 1) ? d[i - 1] : (u(rng) * (1 + spread) + 1 - spread) / 2;
        if (k % 5 == 0)
            d = d.cwiseAbs() + Eigen::Matrix<double, n, 1>::Constant(1e-3); // positive definite
        Mat R;
        for (int i = 0; i < n * n; ++i)
            R.data()[i] = u(rng);
        const Eigen::Matrix<double, n, n> Q = Eigen::HouseholderQR<Eigen::Matrix<double, n, n>>(R).householderQ();
        const Eigen::Matrix<double, n, n> A = Q * d.asDiagonal() * Q.transpose();
        const Eigen::Matrix<double, n, n> expected = project_psd<n>(A);
        Mat projected = A;
        const bool changed = gpu::project_psd<n>(projected.data());
        EXPECT_LE((Eigen::Matrix<double, n, n>(projected) - expected).norm(), 1e-13 * A.norm()) << "case " << k;
        if (d.minCoeff() > 0) {
            EXPECT_FALSE(changed);
            const bool unchanged = Eigen::Matrix<double, n, n>(projected) == A;
            EXPECT_TRUE(unchanged) << "a positive definite matrix is returned unchanged";
        }
        if (d.minCoeff() < -1e-3)
            EXPECT_TRUE(changed);
    }
}

TEST(GpuProjectPsd, EqualsCpuProjection)
{
    compare_projection<4>(1.0);
    compare_projection<9>(1.0);
    compare_projection<9>(1e-6);
}

TEST(GpuProjectPsd, EigenDecompositionReconstructs)
{
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-1, 1);
    Eigen::Matrix<double, 9, 9, Eigen::RowMajor> A;
    for (int i = 0; i < 81; ++i)
        A.data()[i] = u(rng);
    A = (A + A.transpose()).eval();
    double d[9];
    Eigen::Matrix<double, 9, 9, Eigen::RowMajor> V;
    gpu::symmetric_eigen<9>(A.data(), d, V.data());
    const Eigen::Matrix<double, 9, 9> back
        = V * Eigen::Map<Eigen::Matrix<double, 9, 1>>(d).asDiagonal() * V.transpose();
    EXPECT_LE((back - Eigen::Matrix<double, 9, 9>(A)).norm(), 1e-14 * A.norm());
    EXPECT_LE((V.transpose() * V - Eigen::Matrix<double, 9, 9>::Identity()).norm(), 1e-14);
}

} // namespace
