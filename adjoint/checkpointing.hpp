#pragma once
/// @file checkpointing.hpp
/// A memory-bounded adjoint gradient (docs/math.md "Checkpointing"): the forward
/// run keeps the state of every step's record only at checkpoints, and the
/// backward sweep recomputes each segment between two checkpoints from the first
/// one before sweeping it. The forward is deterministic, so the gradient is the
/// full-memory one (adjoint_gradient()) to round-off.
///
/// Schedule with stride s over T steps and an integrator that reads h committed
/// states (h = 2 for BDF2, else 1): checkpoints c_i = i s (i = 1..m,
/// m = ceil(T/s) - 1) keep the records c_i - h + 1 .. c_i; the last segment
/// (c_m, T] is kept whole. Backward, segment (c_i, c_{i+1}] is recomputed from
/// c_i, seeded, swept and released. At most h m + s records hold their state at
/// once (checkpoint_memory_bound()); m (s - h) steps are recomputed, fewer than T.

#include "adjoint/adjoint.hpp"

#include <functional>

namespace diffipc {

struct CheckpointSettings {
    enum class Mode {
        NONE, ///< every record keeps its state (the default)
        STRIDE, ///< checkpoints every `stride` steps, segments recomputed backward
    };
    Mode mode = Mode::NONE;
    /// Steps per segment in STRIDE mode; 0 picks ceil(sqrt(h T)), which minimizes
    /// the bound h (T/s - 1) + s (h: the integrator's history, Simulator::history()).
    int stride = 0;
};

/// What a checkpointed gradient held and recomputed, and what it cost.
struct CheckpointStatistics {
    int steps = 0; ///< T
    int stride = 0; ///< s used (T in NONE mode)
    int checkpoints = 0; ///< interior checkpoints m
    /// Most committed-step records holding their state at once (the initial state,
    /// always held, and the simulator's copy of its last attempt are not counted).
    int peak_stored_states = 0;
    size_t peak_stored_bytes = 0; ///< bytes of those records' states at that peak (StepRecord::state_bytes())
    int bound_stored_states = 0; ///< checkpoint_memory_bound() for this run
    int recomputed_steps = 0;
    double forward_time = 0; ///< the forward run, the objective's observe() included (s)
    double recompute_time = 0; ///< restores and recomputed steps (s)
    double adjoint_time = 0; ///< seeding and the backward steps (s)
    /// (forward + recompute + adjoint) / forward.
    double cost_ratio = 0;
    AdjointStatistics adjoint; ///< of the backward sweep
};

/// An objective as a checkpointed gradient shows it the run: every state once in
/// the forward (to compute its value and whatever its seed needs globally, such
/// as a p-norm's total), then the states again segment by segment backward (to
/// seed them). A state is readable only during these calls: state k is
/// (sim.trajectory().initial_positions, initial_velocities) for k = 0 and
/// sim.trajectory().steps[k-1] otherwise.
struct StreamedObjective {
    /// Forward: state k is held (k = 0, then 1..T in order).
    std::function<void(const Simulator& sim, int k)> observe;
    /// Backward, after observe() saw every state: adds dJ/dx_k and dJ/dv_k for
    /// k = first..last into seed.positions[k] and seed.velocities[k] (T + 1 entries,
    /// the others are not read), and J's explicit partials into
    /// seed.explicit_partials in any one call (they are added and cleared after each).
    /// Segments come from the last (last = T) to the first (first = 0); the states
    /// first..last hold their state, and so does state T.
    std::function<void(const Simulator& sim, int first, int last, StateSeed& seed)> seed;
};

/// @brief Most records the schedule holds at once: h (ceil(T/s) - 1) + s, at most T.
/// @param steps T, @param stride s >= 1, @param history h (1 or 2)
int checkpoint_memory_bound(int steps, int stride, int history);

/// @brief Runs the simulator's scene forward and returns dJ/dp by the adjoint,
/// holding only what `settings` allows (the file's header).
/// @param sim       a simulator that has not stepped yet (its scene's parameters
///                  fixed, a fixed barrier stiffness as for adjoint_gradient());
///                  afterwards its trajectory holds the states of the final h
///                  records only (all in NONE mode) and it stands at step T
/// @param objective observe() and seed() must both be set
/// @param request   the parameter blocks to compute
/// @param stats     optional: memory, recomputation and timings
/// @throws AdjointError if the forward run fails (its message) or as adjoint_gradient();
///         std::invalid_argument for a stepped simulator, missing callbacks or a stride < 0;
///         also if a recomputed step does not converge (the forward was not deterministic).
ParameterGradient checkpointed_gradient(Simulator& sim, const StreamedObjective& objective,
    const ParameterRequest& request, const CheckpointSettings& settings, CheckpointStatistics* stats = nullptr);

} // namespace diffipc
