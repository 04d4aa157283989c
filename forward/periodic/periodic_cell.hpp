#pragma once
/// @file periodic_cell.hpp
/// A periodic scene's step solve (docs/scene_format.md, "periodic"; docs/math.md, "Periodic
/// cells"): the step's full-space problem in the cell's reduced unknowns q = [w, G], the
/// prescribed components of G at the step's time and the pinned class as q's constrained
/// entries, solved by the Newton solver; and the cell-average stress of a potential.

#include "forward/periodic/periodic_map.hpp"
#include "forward/periodic/periodic_potential.hpp"
#include "forward/scene/scene.hpp"
#include "forward/solver/linear_solver.hpp"
#include "forward/solver/newton.hpp"

#include <memory>
#include <vector>

namespace diffipc {

class PeriodicCell {
public:
    /// @param full the step's full-space problem (weights, targets set by the simulator per step)
    /// @param full_assembler an assembler of the full mesh (scratch for the reduced Hessian)
    PeriodicCell(const Scene& scene, const Problem& full, SparseAssembler& full_assembler);

    const PeriodicMap& map() const { return m_map; }
    /// The cell's vertex classes.
    const PeriodicPairing& pairing() const { return m_scene.periodic.pairing; }
    /// The class whose fluctuation is fixed at zero (rigid translation removed): the class of the
    /// vertex nearest the box's lower corner.
    Index pinned_class() const { return m_pinned; }
    /// The constrained entries of q: the pinned class's fluctuation and G's prescribed components.
    const std::vector<char>& constrained() const { return m_constrained; }
    /// Whether G's component (i, j) is prescribed.
    bool prescribed(int i, int j) const { return m_scene.periodic.gradient[size_t(i * m_scene.dim + j)].has_value(); }

    /// @brief Solves the step ending at time t from the committed positions x and macro gradient
    /// G (d^2 values, row-major): G's prescribed components move to their values at t, the free
    /// ones and the fluctuation are solved for. On success x and G are the step's state.
    /// `given`: G's values at t (d^2, SimulationParameters::macro_gradient) for its prescribed
    /// components instead of the expressions.
    NewtonResult solve(VectorXd& x, VectorXd& G, double t, const NewtonSettings& settings, double force_scale,
        double step_scale, const VectorXd* given = nullptr);
    /// @brief solve()'s unknowns: q at the committed x and G, and its target (the pinned class at 0,
    /// G's prescribed components at their values at t; the free entries q's). What the GPU's solve of
    /// the step (DeviceSolver::solve_periodic) takes too.
    /// @throws InputError naming periodic.gradient if a prescribed value is not finite
    void step_unknowns(
        const VectorXd& x, const VectorXd& G, double t, const VectorXd* given, VectorXd& q, VectorXd& target) const;
    /// G's prescribed components at time t (d^2 values, 0 in the free ones): row k - 1 of
    /// `given` if not null, else the scene's expressions.
    VectorXd prescribed_values(double t, const MatrixXd* given = nullptr, int k = 0) const;

    /// |Y|: the box's volume (area in 2D).
    double volume() const { return m_volume; }
    /// The cell-average first Piola stress of `potential` (weight 1) at x, d^2 values row-major:
    /// (1/|Y|) d potential / dG, |Y| the box's volume.
    VectorXd average_stress(const Potential& potential, const VectorXd& x) const;

private:
    const Scene& m_scene;
    PeriodicMap m_map;
    PeriodicPotential m_potential;
    Problem m_reduced;
    SparseAssembler m_assembler;
    LinearSolver m_linear;
    std::vector<char> m_constrained;
    Index m_pinned = 0;
    double m_volume = 1;
};

} // namespace diffipc
