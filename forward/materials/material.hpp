#pragma once
/// @file material.hpp
/// Hyperelastic energy densities Psi(F; mu, lambda) with first Piola-Kirchhoff
/// stress P = dPsi/dF and its derivative dP/dF, on Eigen matrices: the CPU's
/// view of the laws in forward/kernels/material/ (the GPU runs the same code).
/// Lame parameters are passed per call so that every element can carry its own
/// (they will be optimized). 2D models are plane strain: the same formulas with d = 2.
///
/// Flattening of F and P: index(i, j) = i * dim + j (row-major), so
/// stress_derivative(F)(index(i,j), index(k,l)) = dP_ij / dF_kl.

#include "forward/kernels/material/material_model.hpp"

#include <Eigen/Core>

#include <memory>
#include <string>

namespace diffipc {

// One enum for both paths; the names are registered beside it.
using kernels::MaterialModel;

/// @brief Parses a law's name (kernels::MATERIAL_MODEL_NAMES: "linear", "stvk", "neo_hookean",
/// "stable_neo_hookean").
/// @throws InputError naming `field` for any other string.
MaterialModel parse_material_model(const std::string& name, const std::string& field);
std::string to_string(MaterialModel model);

/// Lame parameters from Young's modulus E (Pa) and Poisson's ratio nu (3D and plane strain).
inline double lame_mu(double E, double nu) { return E / (2.0 * (1.0 + nu)); }
inline double lame_lambda(double E, double nu) { return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)); }
/// The 2D lambda of plane stress (a thin sheet, zero normal stress): E nu / (1 - nu^2) =
/// 2 lambda mu / (lambda + 2 mu) of the 3D parameters. Exact for linear elasticity; for the
/// hyperelastic models the usual small-strain substitution (docs/math.md "Materials").
inline double lame_lambda_plane_stress(double E, double nu) { return E * nu / (1.0 - nu * nu); }
inline double lame_lambda(double E, double nu, bool plane_stress)
{
    return plane_stress ? lame_lambda_plane_stress(E, nu) : lame_lambda(E, nu);
}
/// E and nu back from mu and lambda (3D and plane strain, or plane stress).
inline double youngs_modulus_of(double mu, double lambda, bool plane_stress)
{
    return plane_stress ? 2 * mu * (1 + lambda / (2 * mu + lambda)) : mu * (3 * lambda + 2 * mu) / (lambda + mu);
}
inline double poisson_ratio_of(double mu, double lambda, bool plane_stress)
{
    return plane_stress ? lambda / (2 * mu + lambda) : lambda / (2 * (lambda + mu));
}

template <int dim> class Material {
public:
    using Mat = Eigen::Matrix<double, dim, dim>;
    using Tensor = Eigen::Matrix<double, dim * dim, dim * dim>;
    virtual ~Material() = default;

    /// @brief Energy density (J/m^3) at deformation gradient F; +inf where the
    /// model is undefined (J <= 0 for neo-Hookean).
    virtual double energy_density(const Mat& F, double mu, double lambda) const = 0;
    /// @brief First Piola-Kirchhoff stress P = dPsi/dF (Pa).
    virtual Mat stress(const Mat& F, double mu, double lambda) const = 0;
    /// @brief dP/dF as a dim^2 by dim^2 matrix in row-major flattening.
    virtual Tensor stress_derivative(const Mat& F, double mu, double lambda) const = 0;
    virtual MaterialModel model() const = 0;
};

template <int dim> std::unique_ptr<Material<dim>> make_material(MaterialModel model);

/// @brief Cauchy stress \sigma = P F^T / \det F (Pa): the true stress in the deformed
/// configuration, from the first Piola-Kirchhoff stress P (Pa) and the deformation gradient F.
Eigen::Matrix2d cauchy_stress(const Eigen::Matrix2d& P, const Eigen::Matrix2d& F);
Eigen::Matrix3d cauchy_stress(const Eigen::Matrix3d& P, const Eigen::Matrix3d& F);

/// @brief von Mises measure s = \sqrt{\tfrac32 S : S - \tfrac12 (\operatorname{tr} S)^2} (Pa).
/// In 3D this is \sqrt{\tfrac32 \operatorname{dev} S : \operatorname{dev} S}; a 2 by 2 S is
/// taken as the 3D stress with S_{zz} = 0 (the in-plane measure; plane strain's out-of-plane
/// stress is not included). Clamped at 0 against round-off.
double von_mises_stress(const Eigen::Matrix2d& S);
double von_mises_stress(const Eigen::Matrix3d& S);

/// @brief Replaces a symmetric matrix by its closest positive semi-definite
/// matrix (negative eigenvalues set to zero). Matrices that already admit a
/// Cholesky factorization are returned unchanged without an eigen-decomposition.
template <int n> Eigen::Matrix<double, n, n> project_psd(const Eigen::Matrix<double, n, n>& A);
Eigen::MatrixXd project_psd(const Eigen::MatrixXd& A);

} // namespace diffipc
