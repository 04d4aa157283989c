// The element kernels (forward/kernels/element.hpp), which the GPU's device mesh runs, against an
// independent Eigen evaluation of the same element (F = Ds Dm^-1,
// |e| P : dF, |e| B^T A B with Eigen's eigensolver for the projection) and against central
// differences; the small-matrix PSD projection against Eigen's. No GPU needed.

#include "forward/common/types.hpp"
#include "forward/kernels/element.hpp"
#include "forward/materials/material.hpp"

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

/// The element's energy, gradient and Hessian evaluated with Eigen, written here without the
/// kernel's loops: F = Ds Dm^-1, g = |e| B^T vec(P), H = |e| B^T A B with B = dvec(F)/dx, the
/// projection of A by Eigen's SelfAdjointEigenSolver (project_psd).
template <int dim> struct Reference {
    static constexpr int L = dim * (dim + 1);
    double energy;
    Eigen::Matrix<double, L, 1> gradient;
    Eigen::Matrix<double, L, L> hessian, projected;

    Reference(MaterialModel model, const MatrixXd& rest, const MatrixXd& deformed, double mu, double lambda)
    {
        using Mat = Eigen::Matrix<double, dim, dim>;
        Mat Dm, Ds;
        for (int a = 0; a < dim; ++a) {
            Dm.col(a) = (rest.row(a + 1) - rest.row(0)).transpose();
            Ds.col(a) = (deformed.row(a + 1) - deformed.row(0)).transpose();
        }
        const double volume = std::abs(Dm.determinant()) / (dim == 2 ? 2.0 : 6.0);
        const Mat Dinv = Dm.inverse();
        const Mat F = Ds * Dinv;
        // dF_ij / dx_(a,i) = dN_a/dX_j: rows 1..dim of G are Dm^-1, row 0 minus their sum.
        Eigen::Matrix<double, dim + 1, dim> G;
        G.bottomRows(dim) = Dinv;
        G.row(0) = -Dinv.colwise().sum();
        Eigen::Matrix<double, dim * dim, L> B = Eigen::Matrix<double, dim * dim, L>::Zero();
        for (int a = 0; a <= dim; ++a)
            for (int i = 0; i < dim; ++i)
                for (int j = 0; j < dim; ++j)
                    B(i * dim + j, a * dim + i) = G(a, j);
        const auto m = make_material<dim>(model);
        energy = volume * m->energy_density(F, mu, lambda);
        const Mat P = m->stress(F, mu, lambda);
        Eigen::Matrix<double, dim * dim, 1> p;
        for (int i = 0; i < dim; ++i)
            for (int j = 0; j < dim; ++j)
                p[i * dim + j] = P(i, j);
        gradient = volume * B.transpose() * p;
        const Eigen::Matrix<double, dim * dim, dim* dim> A = m->stress_derivative(F, mu, lambda);
        hessian = volume * B.transpose() * A * B;
        projected = volume * B.transpose() * project_psd<dim * dim>(A) * B;
    }
};

template <int dim> void compare_elements(int count)
{
    constexpr int L = dim * (dim + 1);
    std::mt19937 rng(1234 + dim);
    double worst_energy = 0, worst_gradient = 0, worst_hessian[2] = { 0, 0 }, worst_fd[2] = { 0, 0 };
    for (int k = 0; k < count; ++k) {
        const Case c = random_case<dim>(rng, k);
        const auto rest = rows(c.rest), deformed = rows(c.deformed);
        const double J = (c.deformed.bottomRows(dim).rowwise() - c.deformed.row(0)).determinant()
            / (c.rest.bottomRows(dim).rowwise() - c.rest.row(0)).determinant();
        for (MaterialModel model : MODELS) {
            const std::string where = "dim " + std::to_string(dim) + ", " + to_string(model) + ", " + c.kind + " case "
                + std::to_string(k) + ", J " + std::to_string(J);
            const Reference<dim> ref(model, c.rest, c.deformed, c.mu, c.lambda);
            const double energy
                = kernels::element_energy_from_rest<dim>(model, rest.data(), deformed.data(), c.mu, c.lambda);
            if (model == MaterialModel::NEO_HOOKEAN && !(J > 0)) {
                EXPECT_TRUE(std::isinf(ref.energy) && ref.energy > 0) << where;
                EXPECT_TRUE(std::isinf(energy) && energy > 0) << where;
                continue; // its gradient and Hessian are not finite there either
            }
            // The neo-Hookean energies cancel terms of size |e| mu d (ElasticPotential::value_scale).
            double volume;
            double G[(dim + 1) * dim];
            kernels::element_rest_data<dim>(rest.data(), G, volume);
            const double energy_scale = std::abs(ref.energy) + volume * c.mu * dim;
            const double de = std::abs(energy - ref.energy) / energy_scale;
            EXPECT_LE(de, 1e-12) << where << ": energy " << energy << " vs " << ref.energy;
            worst_energy = std::max(worst_energy, de);

            Eigen::Matrix<double, L, 1> g;
            kernels::element_gradient_from_rest<dim>(model, rest.data(), deformed.data(), c.mu, c.lambda, g.data());
            const double dg = (g - ref.gradient).norm() / ref.gradient.norm();
            EXPECT_LE(dg, 1e-12) << where << ": gradient";
            worst_gradient = std::max(worst_gradient, dg);

            // Relative to the true Hessian: a projected one may vanish (all of dP/dF negative).
            const double hessian_scale = ref.hessian.norm();
            Eigen::Matrix<double, L, L, Eigen::RowMajor> H[2];
            for (bool project : { false, true }) {
                kernels::element_hessian_from_rest<dim>(
                    model, rest.data(), deformed.data(), c.mu, c.lambda, project, H[project].data());
                const auto& expected = project ? ref.projected : ref.hessian;
                const double dh = (Eigen::Matrix<double, L, L>(H[project]) - expected).norm() / hessian_scale;
                EXPECT_LE(dh, 1e-12) << where << ": Hessian, project " << project;
                worst_hessian[project] = std::max(worst_hessian[project], dh);
            }
            const double min_eig = Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, L, L>>(H[1]).eigenvalues()[0];
            EXPECT_GE(min_eig, -1e-12 * hessian_scale) << where << ": projected Hessian not PSD";

            // Central differences of the energy and of the gradient along a random direction.
            if (c.kind == "near-inverted")
                continue; // the step would leave the region where the energy is smooth at this scale
            std::vector<double> dir(static_cast<size_t>(L)), plus = deformed, minus = deformed;
            double dir_norm = 0;
            for (double& v : dir) {
                v = std::uniform_real_distribution<double>(-1, 1)(rng);
                dir_norm += v * v;
            }
            const double h = 1e-6 * c.rest.norm() / std::sqrt(dir_norm);
            for (int i = 0; i < L; ++i) {
                plus[size_t(i)] += h * dir[size_t(i)];
                minus[size_t(i)] -= h * dir[size_t(i)];
            }
            const Eigen::Map<const Eigen::Matrix<double, L, 1>> d(dir.data());
            const double fd_energy
                = (kernels::element_energy_from_rest<dim>(model, rest.data(), plus.data(), c.mu, c.lambda)
                      - kernels::element_energy_from_rest<dim>(model, rest.data(), minus.data(), c.mu, c.lambda))
                / (2 * h);
            Eigen::Matrix<double, L, 1> g_plus, g_minus;
            kernels::element_gradient_from_rest<dim>(model, rest.data(), plus.data(), c.mu, c.lambda, g_plus.data());
            kernels::element_gradient_from_rest<dim>(model, rest.data(), minus.data(), c.mu, c.lambda, g_minus.data());
            const double e_fd = std::abs(fd_energy - g.dot(d)) / (g.norm() * d.norm());
            const double h_fd = ((g_plus - g_minus) / (2 * h) - Eigen::Matrix<double, L, L>(H[0]) * d).norm()
                / (hessian_scale * d.norm());
            EXPECT_LE(e_fd, 1e-6) << where << ": gradient against differences of the energy";
            EXPECT_LE(h_fd, 1e-6) << where << ": Hessian against differences of the gradient";
            worst_fd[0] = std::max(worst_fd[0], e_fd);
            worst_fd[1] = std::max(worst_fd[1], h_fd);
        }
    }
    std::printf("dim %d, %d cases x 4 models: worst relative differences against Eigen: energy %.2e, gradient %.2e, "
                "Hessian %.2e, projected Hessian %.2e; against central differences: gradient %.2e, Hessian %.2e\n",
        dim, count, worst_energy, worst_gradient, worst_hessian[0], worst_hessian[1], worst_fd[0], worst_fd[1]);
}

TEST(Element, EnergyGradientHessianAgainstEigenAndDifferences2D) { compare_elements<2>(400); }
TEST(Element, EnergyGradientHessianAgainstEigenAndDifferences3D) { compare_elements<3>(400); }

/// The element kernels are templates over the scalar type: instantiated with long double here, they
/// give the double results to the double's round-off (what dual numbers will build on).
template <int dim> void compare_scalar_types()
{
    constexpr int L = dim * (dim + 1);
    std::mt19937 rng(99 + dim);
    for (int k = 0; k < 40; ++k) {
        const Case c = random_case<dim>(rng, k % 2); // moderate and large deformations
        const auto rest = rows(c.rest), deformed = rows(c.deformed);
        double volume, G[(dim + 1) * dim];
        kernels::element_rest_data<dim>(rest.data(), G, volume);
        long double G_long[(dim + 1) * dim], x_long[L];
        for (int i = 0; i < (dim + 1) * dim; ++i) {
            G_long[i] = G[i];
            x_long[i] = deformed[size_t(i)];
        }
        for (MaterialModel model : MODELS) {
            const double e = kernels::element_energy<dim>(model, G, volume, deformed.data(), c.mu, c.lambda);
            const long double e_long = kernels::element_energy<dim>(model, G_long, volume, x_long, c.mu, c.lambda);
            if (!std::isfinite(e))
                continue; // an inverted neo-Hookean element
            EXPECT_NEAR(double(e_long), e, 1e-12 * (std::abs(e) + volume * c.mu * dim)) << to_string(model);
            double g[L], H[L * L];
            long double g_long[L], H_long[L * L];
            kernels::element_gradient<dim>(model, G, volume, deformed.data(), c.mu, c.lambda, g);
            kernels::element_gradient<dim>(model, G_long, volume, x_long, c.mu, c.lambda, g_long);
            kernels::element_hessian<dim>(model, G, volume, deformed.data(), c.mu, c.lambda, false, H);
            kernels::element_hessian<dim>(model, G_long, volume, x_long, c.mu, c.lambda, false, H_long);
            double g_norm = 0, g_diff = 0, H_norm = 0, H_diff = 0;
            for (int i = 0; i < L; ++i) {
                g_norm += g[i] * g[i];
                g_diff += std::pow(double(g_long[i]) - g[i], 2);
            }
            for (int i = 0; i < L * L; ++i) {
                H_norm += H[i] * H[i];
                H_diff += std::pow(double(H_long[i]) - H[i], 2);
            }
            EXPECT_LE(std::sqrt(g_diff), 1e-12 * std::sqrt(g_norm)) << to_string(model) << ": gradient";
            EXPECT_LE(std::sqrt(H_diff), 1e-12 * std::sqrt(H_norm)) << to_string(model) << ": Hessian";
        }
    }
}

TEST(Element, TemplatesOverTheScalarType)
{
    compare_scalar_types<2>();
    compare_scalar_types<3>();
}

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
            const Eigen::Matrix<double, dim, dim> Fc = F;
            const double psi = m->energy_density(Fc, mu, lambda);
            EXPECT_NEAR(
                kernels::energy_density<dim>(model, F.data(), mu, lambda), psi, 1e-13 * (std::abs(psi) + mu * dim));
            Mat P;
            kernels::stress<dim>(model, F.data(), mu, lambda, P.data());
            const Mat P_cpu = m->stress(Fc, mu, lambda);
            EXPECT_LE((P - P_cpu).norm(), 1e-13 * P_cpu.norm()) << to_string(model);
            Eigen::Matrix<double, n, n, Eigen::RowMajor> A;
            kernels::stress_derivative<dim>(model, F.data(), mu, lambda, A.data());
            const Eigen::Matrix<double, n, n> A_cpu = m->stress_derivative(Fc, mu, lambda);
            EXPECT_LE((Eigen::Matrix<double, n, n>(A) - A_cpu).norm(), 1e-13 * A_cpu.norm()) << to_string(model);
        }
    }
}

// The Eigen adapter (make_material) hands F over in the kernel's row-major layout and reads P and
// dP/dF back from it.
TEST(KernelMaterial, EigenAdapterMatchesKernel)
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
        const bool changed = kernels::project_psd<n>(projected.data());
        EXPECT_LE((Eigen::Matrix<double, n, n>(projected) - expected).norm(), 1e-13 * A.norm()) << "case " << k;
        if (d.minCoeff() > 0) {
            EXPECT_FALSE(changed);
            const bool unchanged = Eigen::Matrix<double, n, n>(projected) == A;
            EXPECT_TRUE(unchanged) << "a positive definite matrix is returned unchanged";
        }
        if (d.minCoeff() < -1e-3) {
            EXPECT_TRUE(changed);
        }
    }
}

TEST(ProjectPsd, EqualsEigenProjection)
{
    compare_projection<4>(1.0);
    compare_projection<9>(1.0);
    compare_projection<9>(1e-6);
}

TEST(ProjectPsd, EigenDecompositionReconstructs)
{
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-1, 1);
    Eigen::Matrix<double, 9, 9, Eigen::RowMajor> A;
    for (int i = 0; i < 81; ++i)
        A.data()[i] = u(rng);
    A = (A + A.transpose()).eval();
    double d[9];
    Eigen::Matrix<double, 9, 9, Eigen::RowMajor> V;
    kernels::symmetric_eigen<9>(A.data(), d, V.data());
    const Eigen::Matrix<double, 9, 9> back
        = V * Eigen::Map<Eigen::Matrix<double, 9, 1>>(d).asDiagonal() * V.transpose();
    EXPECT_LE((back - Eigen::Matrix<double, 9, 9>(A)).norm(), 1e-14 * A.norm());
    EXPECT_LE((V.transpose() * V - Eigen::Matrix<double, 9, 9>::Identity()).norm(), 1e-14);
}

} // namespace
