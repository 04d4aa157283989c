// The closed-form eigensystems of dP/dF (forward/kernels/material/eigensystem.hpp), with which the
// GPU projects the elastic Hessian: the signed SVD against its definition, the eigensystem
// against the kernels' dP/dF (forward/kernels/material/material.hpp), and the projection against
// Eigen's numerical one (project_psd, SelfAdjointEigenSolver). No GPU needed.

#include "forward/kernels/material/eigensystem.hpp"
#include "forward/materials/material.hpp"

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

using namespace diffipc;

namespace {

template <int dim> using RowMat = Eigen::Matrix<double, dim, dim, Eigen::RowMajor>;

constexpr MaterialModel ISOTROPIC[]
    = { MaterialModel::STVK, MaterialModel::NEO_HOOKEAN, MaterialModel::STABLE_NEO_HOOKEAN };
constexpr MaterialModel ALL[]
    = { MaterialModel::LINEAR, MaterialModel::STVK, MaterialModel::NEO_HOOKEAN, MaterialModel::STABLE_NEO_HOOKEAN };

template <int dim> RowMat<dim> random_rotation(std::mt19937& rng)
{
    std::uniform_real_distribution<double> u(-1, 1);
    RowMat<dim> R;
    for (int i = 0; i < dim * dim; ++i)
        R.data()[i] = u(rng);
    RowMat<dim> Q
        = Eigen::Matrix<double, dim, dim>(Eigen::HouseholderQR<Eigen::Matrix<double, dim, dim>>(R).householderQ());
    if (Q.determinant() < 0)
        Q.col(0) *= -1;
    return Q;
}

/// Deformation gradients of many kinds, `kind` names the one made: random near identity and large,
/// near-inverted, inverted (det < 0), pure rotations, the identity, and repeated or nearly repeated
/// singular values (R1 diag(a, a, b) R2), where the eigenvectors are not unique.
template <int dim> RowMat<dim> make_F(std::mt19937& rng, int which, std::string& kind)
{
    std::uniform_real_distribution<double> u(-1, 1);
    RowMat<dim> F = RowMat<dim>::Identity();
    Eigen::Matrix<double, dim, 1> s;
    switch (which % 8) {
    case 0:
        kind = "moderate";
        for (int i = 0; i < dim * dim; ++i)
            F.data()[i] += 0.2 * u(rng);
        return F;
    case 1:
        kind = "large";
        for (int i = 0; i < dim * dim; ++i)
            F.data()[i] += 0.8 * u(rng);
        return F;
    case 2:
        kind = "near-inverted";
        for (int i = 0; i < dim; ++i)
            s[i] = 0.5 + std::abs(u(rng));
        s[dim - 1] = std::pow(10.0, -2 - 2 * std::abs(u(rng)));
        break;
    case 3:
        kind = "inverted";
        for (int i = 0; i < dim; ++i)
            s[i] = 0.5 + std::abs(u(rng));
        s[dim - 1] *= -0.5;
        break;
    case 4:
        kind = "rotation";
        s.setOnes();
        break;
    case 5:
        kind = "identity";
        return F;
    case 6:
        kind = "repeated singular values";
        s.setConstant(0.6 + 0.8 * std::abs(u(rng)));
        if (dim == 3 && which % 16 == 6)
            s[2] = 0.6 + 0.8 * std::abs(u(rng));
        break;
    default:
        kind = "nearly repeated singular values";
        s.setConstant(0.6 + 0.8 * std::abs(u(rng)));
        s[1] *= 1 + 1e-9 * u(rng);
        break;
    }
    return random_rotation<dim>(rng) * s.asDiagonal() * random_rotation<dim>(rng);
}

template <int dim> void check_signed_svd()
{
    std::mt19937 rng(41 + dim);
    for (int k = 0; k < 400; ++k) {
        std::string kind;
        const RowMat<dim> F = make_F<dim>(rng, k, kind);
        RowMat<dim> U, V;
        Eigen::Matrix<double, dim, 1> s;
        ASSERT_TRUE(kernels::signed_svd<dim>(F.data(), U.data(), s.data(), V.data())) << kind;
        const std::string where = "dim " + std::to_string(dim) + ", " + kind + " case " + std::to_string(k);
        EXPECT_LE((U * s.asDiagonal() * V.transpose() - F).norm(), 1e-14 * F.norm()) << where;
        EXPECT_LE((U.transpose() * U - RowMat<dim>::Identity()).norm(), 1e-14) << where;
        EXPECT_LE((V.transpose() * V - RowMat<dim>::Identity()).norm(), 1e-14) << where;
        EXPECT_NEAR(U.determinant(), 1.0, 1e-14) << where;
        EXPECT_NEAR(V.determinant(), 1.0, 1e-14) << where;
        for (int i = 0; i + 1 < dim; ++i) {
            EXPECT_GE(s[i], std::abs(s[i + 1]) - 1e-14 * F.norm()) << where << ": order";
            EXPECT_GT(s[i], 0) << where;
        }
        EXPECT_EQ(s[dim - 1] < 0, F.determinant() < 0) << where << ": sign of the last singular value";
        // The magnitudes are Eigen's singular values.
        const auto reference = Eigen::JacobiSVD<Eigen::Matrix<double, dim, dim>>(F).singularValues();
        EXPECT_LE((s.cwiseAbs() - reference).norm(), 1e-14 * F.norm()) << where;
    }
}

TEST(SignedSvd, FactorsIntoRotationsAndSignedSingularValues)
{
    check_signed_svd<2>();
    check_signed_svd<3>();
}

TEST(SignedSvd, RankDeficientMatricesAreRefused)
{
    // Rank 1 in 3D: U's second column is not determined, the caller falls back.
    const double F3[9] = { 1, 2, 3, 2, 4, 6, -1, -2, -3 };
    double U[9], s[3], V[9];
    EXPECT_FALSE(kernels::signed_svd<3>(F3, U, s, V));
    const double zero[4] = { 0, 0, 0, 0 };
    double U2[4], s2[2], V2[4];
    EXPECT_FALSE(kernels::signed_svd<2>(zero, U2, s2, V2));
    // Rank 2 in 3D is fine (a flattened element): s = (.., .., 0).
    const double flat[9] = { 1, 0, 0, 0, 2, 0, 0, 0, 0 };
    ASSERT_TRUE(kernels::signed_svd<3>(flat, U, s, V));
    EXPECT_EQ(s[0], 2.0);
    EXPECT_EQ(s[1], 1.0);
    EXPECT_LE(std::abs(s[2]), 1e-15);
}

/// The unclamped closed-form eigensystem sums to dP/dF, and its projection equals the CPU's
/// numerical one, on every kind of F, for Lame parameters of many ratios.
template <int dim> void check_eigensystem()
{
    constexpr int n = dim * dim;
    using Big = Eigen::Matrix<double, n, n, Eigen::RowMajor>;
    std::mt19937 rng(97 + dim);
    std::uniform_real_distribution<double> u(-1, 1);
    double worst_reconstruction = 0, worst_projection = 0;
    int changed_count = 0, total = 0;
    for (int k = 0; k < 800; ++k) {
        std::string kind;
        const RowMat<dim> F = make_F<dim>(rng, k, kind);
        const double mu = std::pow(10.0, 3 + 3 * std::abs(u(rng))), lambda = mu * std::pow(10.0, 1.5 * u(rng));
        RowMat<dim> U, V;
        Eigen::Matrix<double, dim, 1> s;
        ASSERT_TRUE(kernels::signed_svd<dim>(F.data(), U.data(), s.data(), V.data()));
        // Both dP/dF's formulas and the eigensystem lose accuracy with the conditioning of F (the
        // neo-Hookean F^{-T} = cof F / det F): round-off times cond F.
        const double tolerance = 1e-13 * std::max(1.0, s[0] / std::abs(s[dim - 1]));
        for (MaterialModel model : ALL) {
            if (model == MaterialModel::NEO_HOOKEAN && !(F.determinant() > 0))
                continue; // not defined there (the line search keeps J > 0)
            const std::string where = "dim " + std::to_string(dim) + ", model " + std::to_string(int(model)) + ", "
                + kind + " case " + std::to_string(k);
            Big A;
            kernels::stress_derivative<dim>(model, F.data(), mu, lambda, A.data());
            if (model != MaterialModel::LINEAR) {
                Big back;
                kernels::isotropic_stress_derivative_from_eigensystem<dim>(
                    model, U.data(), s.data(), V.data(), mu, lambda, false, back.data());
                const double d = (back - A).norm() / A.norm();
                EXPECT_LE(d, tolerance) << where << ": the eigensystem does not sum to dP/dF";
                worst_reconstruction = std::max(worst_reconstruction, d / tolerance * 1e-13);
            }
            const Eigen::Matrix<double, n, n> expected = project_psd<n>(Eigen::Matrix<double, n, n>(A));
            Big projected = A;
            const bool changed = kernels::project_stress_derivative<dim>(model, F.data(), mu, lambda, projected.data());
            const double d = (Eigen::Matrix<double, n, n>(projected) - expected).norm() / A.norm();
            EXPECT_LE(d, tolerance) << where << ": projection";
            worst_projection = std::max(worst_projection, d / tolerance * 1e-13);
            if (!changed) {
                EXPECT_TRUE(projected == A) << where << ": reported unchanged but changed";
            }
            changed_count += changed;
            ++total;
            const double min_eig
                = Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, n, n>>(Eigen::Matrix<double, n, n>(projected))
                      .eigenvalues()[0];
            EXPECT_GE(min_eig, -1e-12 * A.norm()) << where << ": not positive semi-definite";
        }
    }
    // The cases must exercise the projection, not only the Cholesky shortcut.
    EXPECT_GT(changed_count, total / 4);
    std::printf("dim %d: %d of %d matrices projected; worst relative differences divided by "
                "max(1, cond F): eigensystem vs dP/dF %.2e, projection vs the CPU's numerical one %.2e\n",
        dim, changed_count, total, worst_reconstruction, worst_projection);
}

TEST(ClosedFormEigensystem, SumsToStressDerivativeAndProjectsAsEigen2D) { check_eigensystem<2>(); }
TEST(ClosedFormEigensystem, SumsToStressDerivativeAndProjectsAsEigen3D) { check_eigensystem<3>(); }

TEST(ClosedFormEigensystem, LinearElasticityIsLeftUnchangedWhenPositiveSemiDefinite)
{
    const double F[9] = { 1.1, 0.2, 0, -0.1, 0.9, 0.3, 0, 0.05, 1.0 };
    using Big = Eigen::Matrix<double, 9, 9, Eigen::RowMajor>;
    Big A;
    kernels::stress_derivative<3>(MaterialModel::LINEAR, F, 2.0, 3.0, A.data());
    Big projected = A;
    EXPECT_FALSE(kernels::project_stress_derivative<3>(MaterialModel::LINEAR, F, 2.0, 3.0, projected.data()));
    EXPECT_TRUE(projected == A);
    // lambda < -2 mu / 3: the volumetric eigenvalue is negative and removed.
    kernels::stress_derivative<3>(MaterialModel::LINEAR, F, 2.0, -3.0, A.data());
    projected = A;
    EXPECT_TRUE(kernels::project_stress_derivative<3>(MaterialModel::LINEAR, F, 2.0, -3.0, projected.data()));
    const Eigen::Matrix<double, 9, 9> expected = project_psd<9>(Eigen::Matrix<double, 9, 9>(A));
    EXPECT_LE((Eigen::Matrix<double, 9, 9>(projected) - expected).norm(), 1e-13 * A.norm());
}

} // namespace
