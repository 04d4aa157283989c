#include "forward/materials/material.hpp"

#include "forward/common/error.hpp"
#include "forward/kernels/material/material.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>

namespace diffipc {

MaterialModel parse_material_model(const std::string& name, const std::string& field)
{
    std::string expected;
    for (int m = 0; m < kernels::MATERIAL_MODEL_COUNT; ++m) {
        if (name == kernels::MATERIAL_MODEL_NAMES[m])
            return MaterialModel(m);
        expected += std::string(m == 0                               ? ""
                            : m + 1 == kernels::MATERIAL_MODEL_COUNT ? " or "
                                                                     : ", ")
            + kernels::MATERIAL_MODEL_NAMES[m];
    }
    throw InputError(field, "unknown material model '" + name + "' (expected " + expected + ")");
}

std::string to_string(MaterialModel model)
{
    const int m = int(model);
    return m >= 0 && m < kernels::MATERIAL_MODEL_COUNT ? kernels::MATERIAL_MODEL_NAMES[m] : "unknown";
}

namespace {

    /// A law of forward/kernels/material/material.hpp on Eigen matrices. The kernels take F and
    /// return P row-major, Eigen stores column-major: RowMajor maps and copies convert.
    template <int dim> class KernelMaterial final : public Material<dim> {
    public:
        using Mat = typename Material<dim>::Mat;
        using Tensor = typename Material<dim>::Tensor;
        using RowMat = Eigen::Matrix<double, dim, dim, Eigen::RowMajor>;
        using RowTensor = Eigen::Matrix<double, dim * dim, dim * dim, Eigen::RowMajor>;

        explicit KernelMaterial(MaterialModel model)
            : m_model(model)
        {
        }
        double energy_density(const Mat& F, double mu, double lambda) const override
        {
            const RowMat Fr = F;
            return kernels::energy_density<dim>(m_model, Fr.data(), mu, lambda);
        }
        Mat stress(const Mat& F, double mu, double lambda) const override
        {
            const RowMat Fr = F;
            RowMat P;
            kernels::stress<dim>(m_model, Fr.data(), mu, lambda, P.data());
            return P;
        }
        Tensor stress_derivative(const Mat& F, double mu, double lambda) const override
        {
            const RowMat Fr = F;
            RowTensor A;
            kernels::stress_derivative<dim>(m_model, Fr.data(), mu, lambda, A.data());
            return A;
        }
        MaterialModel model() const override { return m_model; }

    private:
        MaterialModel m_model;
    };

} // namespace

template <int dim> std::unique_ptr<Material<dim>> make_material(MaterialModel model)
{
    if (int(model) < 0 || int(model) >= kernels::MATERIAL_MODEL_COUNT)
        return nullptr;
    return std::make_unique<KernelMaterial<dim>>(model);
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
