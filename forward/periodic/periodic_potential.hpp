#pragma once
/// @file periodic_potential.hpp
/// A periodic cell's incremental potential in its reduced unknowns q (forward/periodic/
/// periodic_map.hpp): E(q) = E_full(X + P q), gradient P^T g, Hessian P^T H P, and every step
/// certified (CCD, inversion bound) along the linear path P p in positions. The Newton solver
/// runs unchanged on q, with the q-space assembler of periodic_elements().

#include "forward/periodic/periodic_map.hpp"
#include "forward/potentials/potential.hpp"
#include "forward/solver/problem.hpp"
#include "forward/solver/sparse_assembler.hpp"

namespace diffipc {

class PeriodicPotential final : public Potential {
public:
    /// @param full the full-space problem (its potentials and weights); kept by reference
    /// @param full_assembler an assembler built for the full mesh; used as scratch by add_hessian
    PeriodicPotential(const Problem& full, SparseAssembler& full_assembler, const PeriodicMap& map)
        : m_full(full)
        , m_assembler(full_assembler)
        , m_map(map)
    {
    }
    std::string name() const override { return "periodic cell"; }
    double value(const VectorXd& q) const override { return m_full.energy(m_map.positions(q)); }
    double value_scale(const VectorXd& q) const override { return m_full.energy_magnitude(m_map.positions(q)); }
    void add_gradient(const VectorXd& q, double weight, VectorXd& g) const override;
    void add_hessian(const VectorXd& q, double weight, bool project_to_psd, SparseAssembler& H) const override;
    double max_step(const VectorXd& q, const VectorXd& p) const override
    {
        return m_full.max_step(m_map.positions(q), m_map.expand(p));
    }
    bool step_unresolved() const override { return m_full.step_unresolved(); }
    bool end_iteration(const VectorXd& q) override { return m_full.end_iteration(m_map.positions(q)); }

private:
    const Problem& m_full;
    SparseAssembler& m_assembler;
    const PeriodicMap& m_map;
};

/// The q-space elements (for SparseAssembler::build with dim dofs per vertex and
/// num_classes() + dim vertices): each element's vertex classes, then the dim macro
/// pseudo-vertices (row i of G), which every element couples.
MatrixXi periodic_elements(const Mesh& mesh, const PeriodicPairing& pairing);

} // namespace diffipc
