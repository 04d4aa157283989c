#pragma once
/// @file elastic_potential.hpp
/// Total elastic energy Psi(x) = sum_e |e| psi_e(F_e(x)) over P1 elements, each
/// element with its own material model and Lame parameters.

#include "forward/common/parallel.hpp"
#include "forward/fem/fe_space.hpp"
#include "forward/materials/material.hpp"
#include "forward/potentials/potential.hpp"

#include <memory>
#include <vector>

namespace diffipc {

class ElasticPotential : public Potential {
public:
    /// @param space   P1 space (must outlive the potential)
    /// @param models  #E material model per element
    /// @param mu      #E first Lame parameter per element (Pa)
    /// @param lambda  #E second Lame parameter per element (Pa)
    ElasticPotential(const FESpace& space, std::vector<MaterialModel> models, VectorXd mu, VectorXd lambda);
    ~ElasticPotential() override;

    std::string name() const override { return "elastic"; }
    double value(const VectorXd& x) const override;
    /// Round-off scale of value(): |value| plus, for the neo-Hookean models, sum_e |e| mu_e d,
    /// the size of the terms mu/2 (tr F^T F - d) and mu ln J that cancel near rest.
    double value_scale(const VectorXd& x) const override;
    void add_gradient(const VectorXd& x, double weight, VectorXd& g) const override;
    void add_hessian(const VectorXd& x, double weight, bool project_to_psd, SparseAssembler& H) const override;
    /// Shape derivative of direction^T grad Psi (docs/math.md "Adjoint").
    void add_shape_derivative(
        const VectorXd& x, const VectorXd& direction, double weight, VectorXd& d_rest_positions) const override;
    /// @brief Adds weight * d/dmu_e [direction^T grad Psi] and d/dlambda_e to
    /// dmu and dlambda (#E each); every material law is linear in (mu, lambda).
    void add_lame_derivative(
        const VectorXd& x, const VectorXd& direction, double weight, VectorXd& dmu, VectorXd& dlambda) const;
    /// Inversion bound: no element may lose more than 90% of its volume along the step.
    double max_step(const VectorXd& x, const VectorXd& p) const override;

    /// @brief Replaces the per-element Lame parameters (#E each).
    void set_lame_parameters(const VectorXd& mu, const VectorXd& lambda);
    const VectorXd& mu() const { return m_mu; }
    const VectorXd& lambda() const { return m_lambda; }
    const std::vector<MaterialModel>& models() const { return m_models; }
    const FESpace& space() const { return m_space; }

    /// @brief #E by dim*dim first Piola-Kirchhoff stress per element (row-major flattening).
    MatrixXd element_stresses(const VectorXd& x) const;
    /// @brief #E by 9 Cauchy stress \sigma = P F^T / \det F per element (Pa), the 3 by 3 tensor
    /// flattened row-major (xx, xy, xz, yx, ...); in 2D the in-plane 2 by 2 stress padded with
    /// zeros (the plane-strain \sigma_{zz} is not included).
    MatrixXd element_cauchy_stresses(const VectorXd& x) const;

private:
    struct Impl;
    const FESpace& m_space;
    std::vector<MaterialModel> m_models;
    VectorXd m_mu, m_lambda;
    std::unique_ptr<Impl> m_impl;
    /// Scratch for per-element gradients (and shape derivatives), gathered per vertex
    /// by m_scatter in element order: the sum of a serial scatter, for any thread count.
    mutable std::vector<double> m_gradient_buffer;
    VertexScatter m_scatter;
};

/// @name Element-level energy, gradient and Hessian of one P1 element.
/// @param rest      (dim+1) by dim rest vertex positions (row per vertex)
/// @param deformed  (dim+1) by dim deformed vertex positions
/// @param mu, lambda Lame parameters (Pa)
/// Gradients and Hessians are w.r.t. the deformed positions flattened vertex-major.
/// @{
double element_energy(MaterialModel model, const MatrixXd& rest, const MatrixXd& deformed, double mu, double lambda);
VectorXd element_gradient(
    MaterialModel model, const MatrixXd& rest, const MatrixXd& deformed, double mu, double lambda);
MatrixXd element_hessian(
    MaterialModel model, const MatrixXd& rest, const MatrixXd& deformed, double mu, double lambda, bool project_to_psd);
/// @}

} // namespace diffipc
