#pragma once
/// @file problem.hpp
/// The incremental potential of one time step as a weighted sum of the
/// potentials the scene needs: E(x) = sum_k w_k E_k(x). The time integrator
/// sets the weights (1 for inertia, c h^2 for the rest; 1 for all in a static solve).

#include "forward/potentials/potential.hpp"
#include "forward/solver/sparse_assembler.hpp"

#include <string>
#include <vector>

namespace diffipc {

class Problem {
public:
    void add(Potential* potential, double weight);
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
        int work; ///< index into work()
    };
    const std::vector<Term>& terms() const { return m_terms; }

    /// The work done on one potential through this problem: how often each of its
    /// methods ran and their wall time. A term whose weight is 0, or whose potential
    /// vanishes() at the time, is skipped and counts nothing.
    struct TermWork {
        std::string name; ///< Potential::name()
        long values = 0; ///< value() and value_scale() calls
        long gradients = 0;
        long hessians = 0;
        long step_bounds = 0; ///< max_step() calls
        double time = 0; ///< s, in all of those
    };
    /// One entry per potential ever added, in the order of their first add (kept after remove()).
    const std::vector<TermWork>& work() const { return m_work; }

private:
    std::vector<Term> m_terms;
    mutable std::vector<TermWork> m_work;
    std::vector<const Potential*> m_work_of; ///< the potential of each work() entry
};

} // namespace diffipc
