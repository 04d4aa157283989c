#pragma once
/// @file cell_optimization.hpp
/// Optimizing a cushion cell's design (issue 15; docs/microstructures.md, "Optimization"): a
/// cell objective (cell_objective.hpp: the quasi-static plateau of cell_design.hpp, the drop
/// test's peak stress of drop_design.hpp) minimized within the family's bounds by any of the
/// optimizers (L-BFGS-B, MMA, ...; shape_opt/optimizer/optimizer.hpp), optionally with some
/// variables held at their starting values. The thicknesses' lower bounds are raised to what the
/// mesh size resolves at the narrowest width the run may reach (check_meshable; not above x0's).
///
/// Between remeshes the optimizer sees J(x) on the reference mesh moved to x
/// (CellShapeMap::moved), a smooth function with its exact gradient; a design the mesh cannot
/// follow (a boundary vertex finds no level set, an element inverts), one that could not be
/// meshed anew (a beam thinner than the mesh size, check_meshable), or whose simulation fails or
/// cannot be differentiated (AdjointError) is rejected (the optimizer backtracks). When an accepted design's moved mesh
/// falls below the quality threshold, the cell is meshed anew there and the optimizer restarts from it without its
/// history (J changes by the remeshing's discretization noise).

#include "shape_opt/microstructure/cell_objective.hpp"
#include "shape_opt/optimizer/optimizer.hpp"

#include <functional>

namespace diffipc {

struct CellOptimizationSettings {
    OptimizerSettings optimizer; ///< its bounds are the family's
    double remesh_quality = 0.3; ///< remesh when the moved mesh's worst mean ratio falls below this
    int max_remeshes = 10;
    std::vector<std::string> fixed; ///< names of variables held at their values in x0
};

/// One accepted iterate.
struct CellIteration {
    int iteration = 0; ///< over the whole run (0: the start)
    int mesh = 0; ///< how many remeshes before it
    double J = 0;
    double gradient_norm = 0; ///< of the projected gradient (inf-norm)
    double quality = 0; ///< worst mean ratio of the moved mesh
    double seconds = 0; ///< since the start
    VectorXd x;
};

/// A trial design the run could not use, and why (the optimizer backtracked from it).
struct CellRejection {
    VectorXd x;
    std::string reason; ///< the meshing, simulation or adjoint error
};

struct CellOptimizationResult {
    VectorXd x; ///< the last accepted design
    DesignValue final; ///< at x, on a new mesh of x (with the gradient)
    std::vector<CellIteration> history;
    int remeshes = 0;
    int evaluations = 0;
    std::vector<CellRejection> rejections; ///< every rejected design, in order
    int rejected() const { return int(rejections.size()); }
    StopReason reason = StopReason::FAILED;
    std::string message;
};

/// @brief Minimizes the design's J from x0.
/// @param progress called after every accepted iterate
/// @throws InputError for x0 outside the bounds or an x0 that cannot be meshed or simulated, or
///         an unknown name in `fixed` (naming "fixed")
CellOptimizationResult optimize_cell(const CellObjective& objective, const VectorXd& x0,
    const CellOptimizationSettings& settings, const std::function<void(const CellIteration&)>& progress = {});

} // namespace diffipc
