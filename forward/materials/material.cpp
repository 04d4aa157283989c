#include "forward/materials/material.hpp"

#include "forward/common/error.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <limits>

namespace diffipc {

MaterialModel parse_material_model(const std::string& name, const std::string& field)
{
    if (name == "linear")
        return MaterialModel::LINEAR;
    if (name == "stvk")
        return MaterialModel::STVK;
    if (name == "neo_hookean")
        return MaterialModel::NEO_HOOKEAN;
    if (name == "stable_neo_hookean")
        return MaterialModel::STABLE_NEO_HOOKEAN;
    throw InputError(
        field, "unknown material model '" + name + "' (expected linear, stvk, neo_hookean or stable_neo_hookean)");
}

std::string to_string(MaterialModel model)
{
    switch (model) {
    case MaterialModel::LINEAR:
        return "linear";
    case MaterialModel::STVK:
        return "stvk";
    case MaterialModel::NEO_HOOKEAN:
        return "neo_hookean";
    case MaterialModel::STABLE_NEO_HOOKEAN:
        return "stable_neo_hookean";
    }
    return "unknown";
}

namespace {

    template <int dim> constexpr int idx(int i, int j) { return i * dim + j; }

    template <int dim> using Mat = Eigen::Matrix<double, dim, dim>;
    template <int dim> using Tensor = Eigen::Matrix<double, dim * dim, dim * dim>;

    /// Linear (small-strain) elasticity: Psi = mu eps:eps + lambda/2 tr(eps)^2, eps = sym(F) - I.
    template <int dim> class LinearElasticity final : public Material<dim> {
    public:
        double energy_density(const Mat<dim>& F, double mu, double lambda) const override
        {
            const Mat<dim> eps = 0.5 * (F + F.transpose()) - Mat<dim>::Identity();
            const double tr = eps.trace();
            return mu * eps.squaredNorm() + 0.5 * lambda * tr * tr;
        }
        Mat<dim> stress(const Mat<dim>& F, double mu, double lambda) const override
        {
            const Mat<dim> eps = 0.5 * (F + F.transpose()) - Mat<dim>::Identity();
            return 2.0 * mu * eps + lambda * eps.trace() * Mat<dim>::Identity();
        }
        Tensor<dim> stress_derivative(const Mat<dim>&, double mu, double lambda) const override
        {
            Tensor<dim> A = Tensor<dim>::Zero();
            for (int i = 0; i < dim; ++i)
                for (int j = 0; j < dim; ++j) {
                    A(idx<dim>(i, j), idx<dim>(i, j)) += mu;
                    A(idx<dim>(i, j), idx<dim>(j, i)) += mu;
                    if (i == j)
                        for (int k = 0; k < dim; ++k)
                            A(idx<dim>(i, i), idx<dim>(k, k)) += lambda;
                }
            return A;
        }
        MaterialModel model() const override { return MaterialModel::LINEAR; }
    };

    /// Saint Venant-Kirchhoff: Psi = mu E:E + lambda/2 tr(E)^2, E = (F^T F - I)/2, P = F S.
    template <int dim> class StVK final : public Material<dim> {
    public:
        static Mat<dim> green(const Mat<dim>& F) { return 0.5 * (F.transpose() * F - Mat<dim>::Identity()); }
        double energy_density(const Mat<dim>& F, double mu, double lambda) const override
        {
            const Mat<dim> E = green(F);
            const double tr = E.trace();
            return mu * E.squaredNorm() + 0.5 * lambda * tr * tr;
        }
        Mat<dim> stress(const Mat<dim>& F, double mu, double lambda) const override
        {
            const Mat<dim> E = green(F);
            return F * (2.0 * mu * E + lambda * E.trace() * Mat<dim>::Identity());
        }
        Tensor<dim> stress_derivative(const Mat<dim>& F, double mu, double lambda) const override
        {
            const Mat<dim> E = green(F);
            const Mat<dim> S = 2.0 * mu * E + lambda * E.trace() * Mat<dim>::Identity();
            const Mat<dim> FFt = F * F.transpose();
            Tensor<dim> A;
            // dP_ij/dF_kl = d_ik S_lj + mu F_il F_kj + mu (F F^T)_ik d_jl + lambda F_ij F_kl
            for (int i = 0; i < dim; ++i)
                for (int j = 0; j < dim; ++j)
                    for (int k = 0; k < dim; ++k)
                        for (int l = 0; l < dim; ++l)
                            A(idx<dim>(i, j), idx<dim>(k, l)) = (i == k ? S(l, j) : 0.0) + mu * F(i, l) * F(k, j)
                                + (j == l ? mu * FFt(i, k) : 0.0) + lambda * F(i, j) * F(k, l);
            return A;
        }
        MaterialModel model() const override { return MaterialModel::STVK; }
    };

    /// Neo-Hookean of the IPC family: Psi = mu/2 (tr(F^T F) - d) - mu ln J + lambda/2 (ln J)^2.
    template <int dim> class NeoHookean final : public Material<dim> {
    public:
        double energy_density(const Mat<dim>& F, double mu, double lambda) const override
        {
            const double J = F.determinant();
            if (!(J > 0))
                return std::numeric_limits<double>::infinity();
            const double lnJ = std::log(J);
            return 0.5 * mu * (F.squaredNorm() - dim) - mu * lnJ + 0.5 * lambda * lnJ * lnJ;
        }
        Mat<dim> stress(const Mat<dim>& F, double mu, double lambda) const override
        {
            const double lnJ = std::log(F.determinant());
            const Mat<dim> FinvT = F.inverse().transpose();
            return mu * (F - FinvT) + lambda * lnJ * FinvT;
        }
        Tensor<dim> stress_derivative(const Mat<dim>& F, double mu, double lambda) const override
        {
            const double lnJ = std::log(F.determinant());
            const Mat<dim> G = F.inverse().transpose();
            Tensor<dim> A;
            // dP_ij/dF_kl = mu d_ik d_jl + (mu - lambda lnJ) G_il G_kj + lambda G_ij G_kl,  G = F^{-T}
            for (int i = 0; i < dim; ++i)
                for (int j = 0; j < dim; ++j)
                    for (int k = 0; k < dim; ++k)
                        for (int l = 0; l < dim; ++l)
                            A(idx<dim>(i, j), idx<dim>(k, l)) = (i == k && j == l ? mu : 0.0)
                                + (mu - lambda * lnJ) * G(i, l) * G(k, j) + lambda * G(i, j) * G(k, l);
            return A;
        }
        MaterialModel model() const override { return MaterialModel::NEO_HOOKEAN; }
    };

    template <int dim> Mat<dim> cofactor(const Mat<dim>& F);
    template <> Mat<2> cofactor<2>(const Mat<2>& F)
    {
        Mat<2> C;
        C << F(1, 1), -F(1, 0), -F(0, 1), F(0, 0);
        return C;
    }
    template <> Mat<3> cofactor<3>(const Mat<3>& F)
    {
        Mat<3> C;
        C.col(0) = F.col(1).cross(F.col(2));
        C.col(1) = F.col(2).cross(F.col(0));
        C.col(2) = F.col(0).cross(F.col(1));
        return C;
    }

    /// d cof(F)_ij / dF_kl, a constant in 2D and linear in F in 3D (Levi-Civita form).
    template <int dim> Tensor<dim> cofactor_derivative(const Mat<dim>& F);
    template <> Tensor<2> cofactor_derivative<2>(const Mat<2>&)
    {
        Tensor<2> D = Tensor<2>::Zero();
        // cof = [[F11, -F10], [-F01, F00]]
        D(idx<2>(0, 0), idx<2>(1, 1)) = 1;
        D(idx<2>(0, 1), idx<2>(1, 0)) = -1;
        D(idx<2>(1, 0), idx<2>(0, 1)) = -1;
        D(idx<2>(1, 1), idx<2>(0, 0)) = 1;
        return D;
    }
    template <> Tensor<3> cofactor_derivative<3>(const Mat<3>& F)
    {
        auto eps = [](int a, int b, int c) { return double((a - b) * (b - c) * (c - a)) / 2.0; };
        Tensor<3> D = Tensor<3>::Zero();
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                for (int k = 0; k < 3; ++k)
                    for (int l = 0; l < 3; ++l) {
                        double s = 0;
                        for (int m = 0; m < 3; ++m)
                            for (int n = 0; n < 3; ++n)
                                s += eps(i, k, m) * eps(j, l, n) * F(m, n);
                        D(idx<3>(i, j), idx<3>(k, l)) = s;
                    }
        return D;
    }

    /// Stable neo-Hookean (Smith, de Goes, Kim 2018, in the rest-stable form of
    /// Kim and Eberle's course notes): Psi = mu/2 (I_C - d) - mu (J - 1) + lambda'/2 (J - 1)^2,
    /// with lambda' = lambda + mu so that it linearizes to linear elasticity with (mu, lambda).
    template <int dim> class StableNeoHookean final : public Material<dim> {
    public:
        double energy_density(const Mat<dim>& F, double mu, double lambda) const override
        {
            const double J = F.determinant(), lp = lambda + mu;
            return 0.5 * mu * (F.squaredNorm() - dim) - mu * (J - 1) + 0.5 * lp * (J - 1) * (J - 1);
        }
        Mat<dim> stress(const Mat<dim>& F, double mu, double lambda) const override
        {
            const double J = F.determinant(), lp = lambda + mu;
            return mu * F + (lp * (J - 1) - mu) * cofactor<dim>(F);
        }
        Tensor<dim> stress_derivative(const Mat<dim>& F, double mu, double lambda) const override
        {
            const double J = F.determinant(), lp = lambda + mu;
            const Mat<dim> C = cofactor<dim>(F);
            Eigen::Matrix<double, dim * dim, 1> c;
            for (int i = 0; i < dim; ++i)
                for (int j = 0; j < dim; ++j)
                    c[idx<dim>(i, j)] = C(i, j);
            return mu * Tensor<dim>::Identity() + lp * c * c.transpose()
                + (lp * (J - 1) - mu) * cofactor_derivative<dim>(F);
        }
        MaterialModel model() const override { return MaterialModel::STABLE_NEO_HOOKEAN; }
    };

} // namespace

template <int dim> std::unique_ptr<Material<dim>> make_material(MaterialModel model)
{
    switch (model) {
    case MaterialModel::LINEAR:
        return std::make_unique<LinearElasticity<dim>>();
    case MaterialModel::STVK:
        return std::make_unique<StVK<dim>>();
    case MaterialModel::NEO_HOOKEAN:
        return std::make_unique<NeoHookean<dim>>();
    case MaterialModel::STABLE_NEO_HOOKEAN:
        return std::make_unique<StableNeoHookean<dim>>();
    }
    return nullptr;
}

template std::unique_ptr<Material<2>> make_material<2>(MaterialModel);
template std::unique_ptr<Material<3>> make_material<3>(MaterialModel);

namespace {
    template <typename Matrix> Matrix project_psd_impl(const Matrix& A)
    {
        Eigen::LLT<Matrix> llt(A);
        if (llt.info() == Eigen::Success)
            return A;
        Eigen::SelfAdjointEigenSolver<Matrix> eig(A);
        const auto d = eig.eigenvalues().cwiseMax(0.0).eval();
        return eig.eigenvectors() * d.asDiagonal() * eig.eigenvectors().transpose();
    }
} // namespace

template <int n> Eigen::Matrix<double, n, n> project_psd(const Eigen::Matrix<double, n, n>& A)
{
    return project_psd_impl(A);
}
template Eigen::Matrix<double, 4, 4> project_psd<4>(const Eigen::Matrix<double, 4, 4>&);
template Eigen::Matrix<double, 9, 9> project_psd<9>(const Eigen::Matrix<double, 9, 9>&);
template Eigen::Matrix<double, 6, 6> project_psd<6>(const Eigen::Matrix<double, 6, 6>&);
template Eigen::Matrix<double, 12, 12> project_psd<12>(const Eigen::Matrix<double, 12, 12>&);

Eigen::MatrixXd project_psd(const Eigen::MatrixXd& A) { return project_psd_impl(A); }

Eigen::Matrix2d cauchy_stress(const Eigen::Matrix2d& P, const Eigen::Matrix2d& F)
{
    return P * F.transpose() / F.determinant();
}
Eigen::Matrix3d cauchy_stress(const Eigen::Matrix3d& P, const Eigen::Matrix3d& F)
{
    return P * F.transpose() / F.determinant();
}

namespace {
    template <typename Matrix> double von_mises_impl(const Matrix& S)
    {
        const double trace = S.trace();
        return std::sqrt(std::max(1.5 * S.squaredNorm() - 0.5 * trace * trace, 0.0));
    }
} // namespace

double von_mises_stress(const Eigen::Matrix2d& S) { return von_mises_impl(S); }
double von_mises_stress(const Eigen::Matrix3d& S) { return von_mises_impl(S); }

} // namespace diffipc
