// Finite-difference checks of every material's element energy gradient and
// Hessian, in 2D and 3D, near rest, at large stretch and at strong compression.

#include "forward/common/error.hpp"
#include "forward/materials/material.hpp"
#include "forward/potentials/elastic_potential.hpp"
#include "tests/forward/test_utils.hpp"

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include <cmath>

using namespace diffipc;

namespace {

struct Case {
    MaterialModel model;
    int dim;
    std::string state;
};

std::string name_of(const testing::TestParamInfo<Case>& info)
{
    return to_string(info.param.model) + "_" + std::to_string(info.param.dim) + "d_" + info.param.state;
}

/// Rest simplex: a perturbed unit corner simplex scaled to 0.1 m.
MatrixXd rest_simplex(int dim)
{
    MatrixXd X = MatrixXd::Zero(dim + 1, dim);
    for (int a = 0; a < dim; ++a)
        X(a + 1, a) = 1.0;
    X += 0.15 * Eigen::Map<const MatrixXd>(test::random_vector((dim + 1) * dim, 7).data(), dim + 1, dim);
    return 0.1 * X;
}

MatrixXd deformation_for(const std::string& state, int dim)
{
    MatrixXd F = MatrixXd::Identity(dim, dim);
    if (state == "near_rest")
        F += 1e-3 * Eigen::Map<const MatrixXd>(test::random_vector(dim * dim, 11).data(), dim, dim);
    else if (state == "stretch") {
        F(0, 0) = 2.5;
        F(1, 1) = 0.8;
        F(0, 1) = 0.3;
    } else if (state == "compression") {
        F(0, 0) = 0.35;
        F(1, 1) = 0.9;
        F(1, 0) = -0.2;
    } else { // "general": a large rotation times a shear
        const double c = std::cos(1.1), s = std::sin(1.1);
        MatrixXd R = MatrixXd::Identity(dim, dim);
        R(0, 0) = c;
        R(0, 1) = -s;
        R(1, 0) = s;
        R(1, 1) = c;
        F += 0.4 * Eigen::Map<const MatrixXd>(test::random_vector(dim * dim, 13).data(), dim, dim);
        F = R * F;
    }
    return F;
}

class MaterialDerivatives : public testing::TestWithParam<Case> {
protected:
    void SetUp() override
    {
        const Case& c = GetParam();
        rest = rest_simplex(c.dim);
        const MatrixXd F = deformation_for(c.state, c.dim);
        deformed = rest * F.transpose();
        deformed
            += 1e-3 * Eigen::Map<const MatrixXd>(test::random_vector((c.dim + 1) * c.dim, 17).data(), c.dim + 1, c.dim);
        ASSERT_GT(F.determinant(), 0);
    }
    double energy(const VectorXd& x) const
    {
        const MatrixXd xm
            = Eigen::Map<const Eigen::Matrix<double, -1, -1, Eigen::RowMajor>>(x.data(), rest.rows(), rest.cols());
        return element_energy(GetParam().model, rest, xm, mu, lambda);
    }
    VectorXd gradient(const VectorXd& x) const
    {
        const MatrixXd xm
            = Eigen::Map<const Eigen::Matrix<double, -1, -1, Eigen::RowMajor>>(x.data(), rest.rows(), rest.cols());
        return element_gradient(GetParam().model, rest, xm, mu, lambda);
    }
    VectorXd flat() const
    {
        Eigen::Matrix<double, -1, -1, Eigen::RowMajor> r = deformed;
        return Eigen::Map<const VectorXd>(r.data(), r.size());
    }

    MatrixXd rest, deformed;
    const double mu = lame_mu(1e6, 0.35), lambda = lame_lambda(1e6, 0.35);
};

// Central differences at several step sizes; the best relative error must be
// small, and shrinking h from 1e-2 to 1e-3 (relative) must reduce the error
// (the truncation error is O(h^2)), so a coincidental match cannot pass.
TEST_P(MaterialDerivatives, GradientMatchesCentralDifferences)
{
    const VectorXd x = flat();
    const double scale = rest.cwiseAbs().maxCoeff();
    for (unsigned seed = 0; seed < 3; ++seed) {
        const VectorXd dir = test::random_vector(x.size(), 100 + seed);
        const double analytic = gradient(x).dot(dir);
        double best = INFINITY;
        std::vector<double> errors;
        for (double h : { 1e-2, 1e-3, 1e-4, 1e-5, 1e-6 }) {
            const double step = h * scale;
            const double fd = (energy(x + step * dir) - energy(x - step * dir)) / (2 * step);
            const double err
                = std::abs(fd - analytic) / std::max(std::abs(analytic), 1e-8 * std::abs(energy(x)) + 1e-300);
            errors.push_back(err);
            best = std::min(best, err);
        }
        EXPECT_LT(best, 1e-7) << "seed " << seed;
        if (errors[0] > 1e-10)
            EXPECT_LT(errors[1], errors[0]) << "no O(h^2) decrease, seed " << seed;
    }
}

TEST_P(MaterialDerivatives, HessianMatchesCentralDifferences)
{
    const VectorXd x = flat();
    const double scale = rest.cwiseAbs().maxCoeff();
    const Eigen::Matrix<double, -1, -1, Eigen::RowMajor> dm = deformed;
    const MatrixXd H = element_hessian(GetParam().model, rest, dm, mu, lambda, false);
    ASSERT_LT((H - H.transpose()).norm(), 1e-10 * H.norm());
    for (unsigned seed = 0; seed < 3; ++seed) {
        const VectorXd dir = test::random_vector(x.size(), 200 + seed);
        const VectorXd analytic = H * dir;
        double best = INFINITY;
        for (double h : { 1e-3, 1e-4, 1e-5, 1e-6 }) {
            const double step = h * scale;
            const VectorXd fd = (gradient(x + step * dir) - gradient(x - step * dir)) / (2 * step);
            best = std::min(best, (fd - analytic).norm() / analytic.norm());
        }
        EXPECT_LT(best, 1e-7) << "seed " << seed;
    }
}

TEST_P(MaterialDerivatives, ProjectedHessianIsPsdAndKeepsPsdInput)
{
    const Eigen::Matrix<double, -1, -1, Eigen::RowMajor> dm = deformed;
    const MatrixXd H = element_hessian(GetParam().model, rest, dm, mu, lambda, false);
    const MatrixXd Hp = element_hessian(GetParam().model, rest, dm, mu, lambda, true);
    Eigen::SelfAdjointEigenSolver<MatrixXd> eig(Hp);
    EXPECT_GE(eig.eigenvalues().minCoeff(), -1e-9 * eig.eigenvalues().cwiseAbs().maxCoeff());
    // Rigid translations stay in the kernel of both.
    VectorXd translation = VectorXd::Zero(H.rows());
    for (Index a = 0; a < H.rows(); a += rest.cols())
        translation[a] = 1.0;
    EXPECT_LT((Hp * translation).norm(), 1e-9 * Hp.norm());
    // Where the true Hessian is already PSD the projection changes nothing.
    Eigen::SelfAdjointEigenSolver<MatrixXd> eig_true(H);
    if (eig_true.eigenvalues().minCoeff() >= 0 && GetParam().state == "near_rest")
        EXPECT_LT((Hp - H).norm(), 1e-9 * H.norm());
}

std::vector<Case> all_cases()
{
    std::vector<Case> cases;
    for (MaterialModel m :
        { MaterialModel::LINEAR, MaterialModel::STVK, MaterialModel::NEO_HOOKEAN, MaterialModel::STABLE_NEO_HOOKEAN })
        for (int dim : { 2, 3 })
            for (const char* state : { "near_rest", "stretch", "compression", "general" })
                cases.push_back({ m, dim, state });
    return cases;
}

INSTANTIATE_TEST_SUITE_P(AllMaterials, MaterialDerivatives, testing::ValuesIn(all_cases()), name_of);

TEST(Material, RestStateIsStressFree)
{
    for (MaterialModel m :
        { MaterialModel::LINEAR, MaterialModel::STVK, MaterialModel::NEO_HOOKEAN, MaterialModel::STABLE_NEO_HOOKEAN }) {
        auto mat = make_material<3>(m);
        EXPECT_NEAR(mat->energy_density(Eigen::Matrix3d::Identity(), 3.0, 5.0), 0.0, 1e-14) << to_string(m);
        EXPECT_LT(mat->stress(Eigen::Matrix3d::Identity(), 3.0, 5.0).norm(), 1e-14) << to_string(m);
    }
}

// Every model linearizes at rest to the same small-strain tensor
// A = mu (I + transpose) + lambda (I (x) I).
TEST(Material, AllModelsLinearizeToLinearElasticity)
{
    const double mu = 2.0, lambda = 7.0;
    const auto reference
        = make_material<3>(MaterialModel::LINEAR)->stress_derivative(Eigen::Matrix3d::Identity(), mu, lambda);
    for (MaterialModel m : { MaterialModel::STVK, MaterialModel::NEO_HOOKEAN, MaterialModel::STABLE_NEO_HOOKEAN }) {
        const auto A = make_material<3>(m)->stress_derivative(Eigen::Matrix3d::Identity(), mu, lambda);
        EXPECT_LT((A - reference).norm(), 1e-12) << to_string(m);
    }
}

TEST(Material, NeoHookeanIsInfiniteWhenInverted)
{
    Eigen::Matrix3d F = Eigen::Matrix3d::Identity();
    F(2, 2) = -0.5;
    EXPECT_TRUE(std::isinf(make_material<3>(MaterialModel::NEO_HOOKEAN)->energy_density(F, 1.0, 1.0)));
}

TEST(Material, UnknownModelNamesTheField)
{
    try {
        parse_material_model("rubber", "bodies[0].material.model");
        FAIL();
    } catch (const InputError& e) {
        EXPECT_EQ(e.field(), "bodies[0].material.model");
    }
}

} // namespace

TEST(Material, CauchyAndVonMisesStress)
{
    // sigma = P F^T / det F: a uniaxial stretch F = diag(2, 1, 1) with P = diag(p, 0, 0) gives sigma_xx = p.
    const Eigen::Matrix3d F = Eigen::Vector3d(2, 1, 1).asDiagonal(), P = Eigen::Vector3d(3, 0, 0).asDiagonal();
    const Eigen::Matrix3d sigma = cauchy_stress(P, F);
    EXPECT_DOUBLE_EQ(sigma(0, 0), 3.0);
    EXPECT_DOUBLE_EQ(sigma.norm(), 3.0);
    EXPECT_DOUBLE_EQ(von_mises_stress(sigma), 3.0); // uniaxial: |sigma_xx|
    EXPECT_DOUBLE_EQ(von_mises_stress(Eigen::Matrix3d(5 * Eigen::Matrix3d::Identity())), 0.0); // hydrostatic
    Eigen::Matrix3d shear = Eigen::Matrix3d::Zero();
    shear(0, 1) = shear(1, 0) = 2;
    EXPECT_DOUBLE_EQ(von_mises_stress(shear), std::sqrt(3.0) * 2); // pure shear: sqrt(3) tau
    // 2D: the 3D measure of the stress padded with zeros.
    Eigen::Matrix2d s2;
    s2 << 1, 0.5, 0.5, -2;
    Eigen::Matrix3d s3 = Eigen::Matrix3d::Zero();
    s3.topLeftCorner<2, 2>() = s2;
    EXPECT_NEAR(von_mises_stress(s2), von_mises_stress(s3), 1e-15);
    EXPECT_NEAR(von_mises_stress(s2), std::sqrt(1 + 2 + 4 + 3 * 0.25), 1e-15);
}
