#pragma once
/// @file parameters.hpp
/// Values that replace a scene's own for one simulation: the canonical
/// parameters that the adjoint differentiates (adjoint/sensitivity.hpp).
/// Every field is optional: an empty vector keeps the scene's value.
///
/// What stays tied to the scene: which vertices a Dirichlet or Neumann region
/// selects, and the points where boundary expressions are evaluated, are taken
/// at the scene's own rest positions; a shape change moves the geometry (and so
/// element volumes, masses, facet areas, the prescribed positions X + g) but not
/// the selection or the expressions' arguments.

#include "forward/common/types.hpp"

namespace diffipc {

struct SimulationParameters {
    /// #V*dim rest positions X (flattened vertex-major), obstacles' vertices included.
    VectorXd rest_positions;
    /// #E per-element Lame parameters (Pa); override E and nu when given.
    VectorXd mu, lambda;
    /// #E per-element Young's modulus (Pa) and Poisson's ratio.
    VectorXd youngs_modulus, poisson_ratio;
    /// #E per-element density (kg/m^3).
    VectorXd density;
    /// Friction coefficient per contact group (bodies, then obstacles).
    VectorXd friction;
    /// #V*dim initial displacement u0 (x_0 = X + u0) and initial velocity v_0;
    /// entries of prescribed dofs are ignored (they follow their prescription).
    VectorXd initial_displacement, initial_velocity;
    /// T by #prescribed dofs: displacement g_k of each prescribed dof at step k
    /// (x = X + g_k), in Simulator::prescribed_dofs() order; replaces the
    /// scene's Dirichlet and obstacle-motion expressions at t_1..t_T.
    MatrixXd prescribed;
    /// > 0: a fixed barrier stiffness (the adaptive rule is off), as in a
    /// differentiated run; 0 keeps the scene's setting.
    double kappa = 0;
    /// Per step k (T entries, or none): the end times of the sub-steps that dynamic step k takes,
    /// increasing in ((k-1) dt, k dt], the last one k dt; an empty entry leaves the step to the
    /// scene (one solve, or time.adaptive's sub-steps). A step given sub-steps takes exactly those
    /// (a failed one fails the step). Simulator::parameters() reports the sub-steps a run took, so
    /// that a run built from them repeats its path: the sub-stepped run that the adjoint
    /// differentiates, held fixed when the other parameters are perturbed.
    std::vector<std::vector<double>> substeps;
    /// Periodic cells: T by d^2, the macro gradient G's values at t_1..t_T (row-major per row);
    /// replaces the scene's expressions for G's prescribed components (free ones are ignored).
    MatrixXd macro_gradient;
};

} // namespace diffipc
