#pragma once
/// @file step_record.hpp
/// What a committed time step leaves behind for output and, later, for the
/// adjoint: the converged state and the solver's diagnostics. Contact and
/// friction issues extend it with their active sets and lagged data.

#include "forward/common/types.hpp"
#include "forward/contact/contact_set.hpp"
#include "forward/contact/friction/friction_potential.hpp"
#include "forward/solver/status.hpp"

#include <algorithm>
#include <limits>
#include <string>
#include <vector>

namespace diffipc {

struct StepRecord {
    int index = 0; ///< 1-based step number
    double time = 0; ///< t_{n+1} (s)
    VectorXd positions; ///< #V*dim deformed positions x_{n+1} (m), flattened vertex-major
    VectorXd velocities; ///< #V*dim (m/s)
    VectorXd accelerations; ///< #V*dim (m/s^2); the scheme's a_{n+1} (exact for Newmark)
    StepStatus status = StepStatus::CONVERGED;
    int newton_iterations = 0;
    double residual = 0; ///< force residual relative to the force scale (docs/math.md)
    double newton_step = 0; ///< last Newton step (m/s dynamic, relative to bbox static)
    double min_volume_ratio = 1; ///< min over elements of volume / rest volume
    double wall_time = 0; ///< s
    int linear_fallbacks = 0;
    int line_search_cuts = 0; ///< backtracking halvings of the step's accepted Newton steps
    /// Newton stopped because its step fell below the round-off of x while the
    /// residual was above tolerance (the residual is then at its floor).
    bool roundoff_limited = false;
    PhaseTimes phases;

    // Automatic load stepping (time.adaptive): 0, 0, 0 for a step solved in one go.
    int substeps = 0; ///< converged sub-steps the step took (its last one ends at `time`)
    int cuts = 0; ///< failed solves (the full step's included) after which the increment was cut
    double min_increment = 0; ///< the smallest converged sub-step's increment (s)
    /// Displacement-controlled solves the step took past a limit point of its load (0: none)
    int control_steps = 0;
    /// Proximal relaxation solves the step took to reach its equilibrium (0: none)
    int relaxation_steps = 0;
    /// A dynamic step solved in sub-steps (time.adaptive, or SimulationParameters::substeps): the
    /// end time of each sub-step, the last one `time`; empty for a step solved in one go and for
    /// static steps (whose state does not depend on the path). Kept by release_state().
    std::vector<double> substep_times;
    /// The state at the end of a dynamic sub-step.
    struct SubState {
        double time = 0;
        VectorXd positions, velocities, accelerations;
    };
    /// A dynamic sub-stepped step's states at the ends of its sub-steps but the last (which is
    /// the record's own): the adjoint sweeps back through them.
    std::vector<SubState> path;

    // Periodic cells (scene "periodic"): d^2 values each, row-major; kept by release_state().
    VectorXd macro_gradient; ///< the macroscopic displacement gradient G at the step's end
    VectorXd macro_stress; ///< the homogenized first Piola stress, elastic and barrier (Simulator::macro_stress; Pa)

    // Contact (when the scene enables it).
    /// Minimum distance (m) over primitive pairs within 1e-2 of the bbox diagonal
    /// of each other and vertex-plane pairs; +inf if none is that close.
    double min_distance = std::numeric_limits<double>::infinity();
    int active_contacts = 0; ///< pairs closer than dmin + dhat at the converged state
    double kappa = 0; ///< barrier stiffness at the end of this step (adaptive kappa may grow within a step)
    ContactSet contacts; ///< the active contacts at the converged state

    // Friction (when some coefficient is positive).
    /// The lagged friction data of the last Newton solve (the converged state satisfies its equations).
    std::vector<FrictionContact> friction;
    /// Force residual (as `residual`) of the problem re-lagged at the converged state:
    /// how far the lagged data is from the state it describes.
    double friction_residual = 0;
    int friction_iterations = 0; ///< Newton solves (lagging iterations) taken
    bool friction_converged = true; ///< friction_residual <= the residual tolerance

    /// @name Checkpointing (adjoint/checkpointing.hpp): a record may be thinned to its
    /// scalar diagnostics and refilled by recomputing its step.
    /// @{
    /// Whether the record holds its state (positions ... friction data), not only its diagnostics.
    bool holds_state() const { return positions.size() > 0; }
    /// @brief Frees the state (positions, velocities, accelerations, contacts, friction data);
    /// index, time, status, kappa and the diagnostics stay.
    void release_state()
    {
        positions = VectorXd();
        velocities = VectorXd();
        accelerations = VectorXd();
        ContactSet().swap(contacts);
        std::vector<FrictionContact>().swap(friction);
        std::vector<SubState>().swap(path);
    }
    /// Bytes held by the state (the heap part that release_state() frees).
    size_t state_bytes() const
    {
        size_t bytes = sizeof(double) * size_t(positions.size() + velocities.size() + accelerations.size())
            + sizeof(Contact) * contacts.capacity() + sizeof(FrictionContact) * friction.capacity();
        for (const SubState& s : path)
            bytes += sizeof(double) * size_t(s.positions.size() + s.velocities.size() + s.accelerations.size());
        return bytes;
    }
    /// @}
};

/// Aggregates over every committed step, kept also when records are forgotten.
struct StepTotals {
    double min_volume_ratio = 1;
    double max_residual = 0;
    int linear_fallbacks = 0;
    int line_search_cuts = 0;
    int roundoff_limited_steps = 0;
    double min_distance = std::numeric_limits<double>::infinity();
    int max_active_contacts = 0;
    int substepped_steps = 0; ///< steps that automatic load stepping split
    int substeps = 0; ///< their sub-steps
    int cuts = 0;
    double min_increment = std::numeric_limits<double>::infinity(); ///< over the split steps (s)
    int control_steps = 0; ///< displacement-controlled solves past limit points
    int relaxation_steps = 0; ///< proximal relaxation solves
    void add(const StepRecord& r)
    {
        if (r.substeps > 0) {
            ++substepped_steps;
            substeps += r.substeps;
            cuts += r.cuts;
            min_increment = std::min(min_increment, r.min_increment);
            control_steps += r.control_steps;
            relaxation_steps += r.relaxation_steps;
        }
        min_volume_ratio = std::min(min_volume_ratio, r.min_volume_ratio);
        max_residual = std::max(max_residual, r.residual);
        linear_fallbacks += r.linear_fallbacks;
        line_search_cuts += r.line_search_cuts;
        roundoff_limited_steps += r.roundoff_limited;
        min_distance = std::min(min_distance, r.min_distance);
        max_active_contacts = std::max(max_active_contacts, r.active_contacts);
    }
};

/// A run: the initial state and every committed step, in order.
struct Trajectory {
    double initial_time = 0;
    VectorXd initial_positions, initial_velocities, initial_accelerations;
    /// The records of steps first_index, first_index + 1, ...: all of them (first_index 1)
    /// unless Simulator::forget_records() dropped the earlier ones (a streamed run).
    std::vector<StepRecord> steps;
    int first_index = 1;
    /// Committed steps, forgotten records included.
    int committed() const { return first_index - 1 + int(steps.size()); }
    /// Whether step k's record is kept (1 <= k <= committed()).
    bool has_record(int k) const { return k >= first_index && k <= committed(); }
    const StepRecord& step(int k) const { return steps[size_t(k - first_index)]; }
    StepRecord& step(int k) { return steps[size_t(k - first_index)]; }
    StepTotals totals;
    /// CONVERGED if every attempted step converged; otherwise the status of the failed step.
    StepStatus final_status = StepStatus::CONVERGED;
    int failed_step = 0; ///< index of the step that failed (0: none)
    std::string failure_message;
    PhaseTimes phases;
    double wall_time = 0;
    int newton_iterations = 0;
    /// d for a periodic cell (its records hold macro_gradient and macro_stress), 0 otherwise.
    int macro_dim = 0;
};

} // namespace diffipc
