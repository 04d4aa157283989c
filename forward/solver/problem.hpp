#pragma once
/// @file problem.hpp
/// The incremental potential of one time step as a weighted sum of the
/// potentials the scene needs: E(x) = sum_k w_k E_k(x). The time integrator
/// sets the weights (1 for inertia, c h^2 for the rest; 1 for all in a static solve).

#include "forward/potentials/potential.hpp"
#include "forward/solver/sparse_assembler.hpp"

#include <vector>

namespace diffipc {

class Problem {
public:
    void add(Potential* potential, double weight) { m_terms.push_back({ potential, weight }); }
    /// Removes the potential's term (std::logic_error if it is not in the problem).
    void remove(const Potential* potential);
    void set_weight(const Potential* potential, double weight);
    double weight(const Potential* potential) const;

    double energy(const VectorXd& x) const;
    /// sum_k |w_k| scale_k(x) (Potential::value_scale): the size of the terms whose sum is
    /// energy(x); its round-off is relative to this, not to |E| (which can cancel to ~0).
    double energy_magnitude(const VectorXd& x) const;
    void gradient(const VectorXd& x, VectorXd& g) const;
    /// Assembles the (projected or true) Hessian into H's fixed pattern (H is zeroed first).
    void hessian(const VectorXd& x, bool project_to_psd, SparseAssembler& H) const;
    /// Largest admissible step along p, the minimum over the potentials.
    double max_step(const VectorXd& x, const VectorXd& p) const;
    /// True if a potential could not certify any step in the last max_step().
    bool step_unresolved() const;
    /// Calls every potential's end_iteration(x); true if any changed itself.
    bool end_iteration(const VectorXd& x) const;

    struct Term {
        Potential* potential;
        double weight;
    };
    const std::vector<Term>& terms() const { return m_terms; }

private:
    std::vector<Term> m_terms;
};

} // namespace diffipc
