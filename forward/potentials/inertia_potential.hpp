#pragma once
/// @file inertia_potential.hpp
/// Inertia term of the incremental potential, 1/2 (x - x~)^T M (x - x~), with
/// lumped or consistent P1 mass; the target x~ is set by the time integrator.

#include "forward/fem/fe_space.hpp"
#include "forward/potentials/potential.hpp"

namespace diffipc {

class InertiaPotential : public Potential {
public:
    /// @param density #E element densities (kg/m^3)
    InertiaPotential(const FESpace& space, const VectorXd& density, bool consistent);

    std::string name() const override { return "inertia"; }
    double value(const VectorXd& x) const override;
    void add_gradient(const VectorXd& x, double weight, VectorXd& g) const override;
    void add_hessian(const VectorXd& x, double weight, bool project_to_psd, SparseAssembler& H) const override;

    /// Shape derivative of direction^T M (x - x~) through the element volumes (x, x~ fixed).
    void add_shape_derivative(
        const VectorXd& x, const VectorXd& direction, double weight, VectorXd& d_rest_positions) const override;
    /// @brief Adds weight * d/drho_e [direction^T M (x - x~)] to d_density (#E).
    void add_density_derivative(const VectorXd& x, const VectorXd& direction, double weight, VectorXd& d_density) const;
    /// @brief Adds weight * d/dp [direction^T M delta] at fixed direction and delta
    /// (#V*dim each) for p = X (d_rest_positions, #V*dim) and rho (d_density, #E); null outputs are skipped.
    void add_mass_derivatives(const VectorXd& direction, const VectorXd& delta, double weight,
        VectorXd* d_rest_positions, VectorXd* d_density) const;

    /// Flattened inertial target x~ (#V*dim).
    void set_target(const VectorXd& target) { m_target = target; }
    const VectorXd& target() const { return m_target; }
    /// M v for a flattened dof vector v.
    VectorXd apply_mass(const VectorXd& v) const;
    /// Lumped nodal masses (#V), also used for gravity loads.
    const VectorXd& lumped_masses() const { return m_lumped; }
    bool consistent() const { return m_consistent; }
    /// #E element densities (kg/m^3).
    const VectorXd& density() const { return m_density; }
    const SparseMatrixd& consistent_matrix() const { return m_matrix; }

private:
    const FESpace& m_space;
    bool m_consistent;
    VectorXd m_lumped;
    VectorXd m_density;
    SparseMatrixd m_matrix;
    VectorXd m_target;
};

/// Work of external forces, -f^T (x - X): constant forces (gravity, tractions) per step.
class ExternalForcePotential : public Potential {
public:
    explicit ExternalForcePotential(const VectorXd& rest)
        : m_rest(rest)
        , m_force(VectorXd::Zero(rest.size()))
    {
    }
    std::string name() const override { return "external_force"; }
    double value(const VectorXd& x) const override { return -m_force.dot(x - m_rest); }
    void add_gradient(const VectorXd&, double weight, VectorXd& g) const override { g -= weight * m_force; }
    void add_hessian(const VectorXd&, double, bool, SparseAssembler&) const override { }
    /// Flattened nodal forces (N), #V*dim.
    void set_force(const VectorXd& f)
    {
        m_force = f;
        m_zero = (f.array() == 0).all();
    }
    bool vanishes() const override { return m_zero; }
    const VectorXd& force() const { return m_force; }

private:
    VectorXd m_rest;
    VectorXd m_force;
    bool m_zero = true;
};

} // namespace diffipc
