#pragma once
#include <string>

namespace diffipc {

/// Outcome of one time step. Only CONVERGED commits; every other value leaves
/// the committed state untouched. Values are stable: they are written to HDF5.
enum class StepStatus {
    CONVERGED = 0,
    INVALID_INITIAL_STATE = 1, ///< start of the step infeasible (inverted element, non-finite energy)
    CCD_UNRESOLVED = 2, ///< reserved for contact
    LINEAR_BREAKDOWN = 3, ///< Cholesky and LDL^T both failed, or a non-finite solution
    LINE_SEARCH_EXHAUSTED = 4, ///< no acceptable step length along the direction
    NEWTON_EXHAUSTED = 5, ///< iteration cap reached before convergence
    FRICTION_EXHAUSTED = 6, ///< reserved for friction lagging
    NON_FINITE = 7, ///< a non-finite gradient or energy appeared during the solve
};

inline std::string to_string(StepStatus s)
{
    switch (s) {
    case StepStatus::CONVERGED:
        return "CONVERGED";
    case StepStatus::INVALID_INITIAL_STATE:
        return "INVALID_INITIAL_STATE";
    case StepStatus::CCD_UNRESOLVED:
        return "CCD_UNRESOLVED";
    case StepStatus::LINEAR_BREAKDOWN:
        return "LINEAR_BREAKDOWN";
    case StepStatus::LINE_SEARCH_EXHAUSTED:
        return "LINE_SEARCH_EXHAUSTED";
    case StepStatus::NEWTON_EXHAUSTED:
        return "NEWTON_EXHAUSTED";
    case StepStatus::FRICTION_EXHAUSTED:
        return "FRICTION_EXHAUSTED";
    case StepStatus::NON_FINITE:
        return "NON_FINITE";
    }
    return "UNKNOWN";
}

/// Wall time (s) per solver phase.
struct PhaseTimes {
    double assembly = 0; ///< gradient and Hessian assembly
    double factorization = 0; ///< numeric factorization, and the symbolic analysis when the pattern grew
    double analysis = 0; ///< of which symbolic analyses (fill-reducing ordering; serial)
    int analyses = 0; ///< symbolic analyses done
    double solve = 0; ///< triangular solves
    double line_search = 0; ///< energy evaluations and the step bound
    // Contact work; already counted inside assembly and line_search above.
    double broad_phase = 0; ///< candidate pairs (static and swept)
    double ccd = 0; ///< narrow-phase continuous collision detection
    double barrier = 0; ///< active-set classification, barrier energy, gradient and Hessian
    PhaseTimes& operator+=(const PhaseTimes& o)
    {
        broad_phase += o.broad_phase;
        ccd += o.ccd;
        barrier += o.barrier;
        assembly += o.assembly;
        factorization += o.factorization;
        analysis += o.analysis;
        analyses += o.analyses;
        solve += o.solve;
        line_search += o.line_search;
        return *this;
    }
    /// The times of a span of a run: later totals minus earlier ones.
    PhaseTimes operator-(const PhaseTimes& o) const
    {
        PhaseTimes d = *this;
        d.broad_phase -= o.broad_phase;
        d.ccd -= o.ccd;
        d.barrier -= o.barrier;
        d.assembly -= o.assembly;
        d.factorization -= o.factorization;
        d.analysis -= o.analysis;
        d.analyses -= o.analyses;
        d.solve -= o.solve;
        d.line_search -= o.line_search;
        return d;
    }
};

} // namespace diffipc
