#pragma once
/// @file streamed.hpp
/// Any Objective as the StreamedObjective of a checkpointed gradient
/// (adjoint/checkpointing.hpp), so that problem files (shape_opt/) can bound the
/// memory of their adjoint without each objective being rewritten to stream.
///
/// The forward run shows every state k once (observe()); the adapter copies the
/// positions, velocities and time of the states that the objective reads
/// (Objective::states_read(), by default every state) into a thin Trajectory of its
/// own. At the first seed() call (the last segment, last = T) it evaluates J and the
/// whole seed (Objective::value() and add_gradient() on the thin trajectory) and then
/// hands the seed out segment by segment.
///
/// What this bounds: the step records (contacts, lagged friction data,
/// accelerations, the solver's per-step data) follow the checkpoint schedule. What
/// it does not: the objective keeps 2 state vectors (x_k, v_k, #V*dim each) per
/// state it reads, T + 1 for an objective over the whole run (a time sum, trapezoid
/// or max_p aggregation), only the listed ones for markers and centre-of-mass
/// tracking or a final-state aggregation; and the seed holds dJ/dx_k, dJ/dv_k for
/// those same states between the first seed() call and their segment.

#include "adjoint/checkpointing.hpp"
#include "objectives/objective.hpp"

namespace diffipc {

class StreamedObjectiveAdapter {
public:
    /// @param objective the objective; must outlive the adapter
    /// @param request   the parameter blocks whose explicit partials the seed carries
    /// @param scale     the seed is scale * dJ (value() stays unscaled J)
    StreamedObjectiveAdapter(const Objective& objective, const ParameterRequest& request, double scale = 1.0);

    /// @brief The callbacks for checkpointed_gradient(), bound to this adapter (which must outlive them).
    /// One run per adapter: observe(sim, 0) starts it afresh.
    StreamedObjective streamed();

    /// @brief J (unscaled) of the run, known from the first seed() call on.
    /// @throws std::logic_error before it.
    double value() const;
    /// States whose x_k and v_k the adapter holds for the objective (T + 1 for all).
    int stored_states() const { return m_stored_states; }
    /// Bytes of those states' positions and velocities.
    size_t stored_bytes() const { return m_stored_bytes; }

private:
    void observe(const Simulator& sim, int k);
    void seed(const Simulator& sim, int first, int last, StateSeed& seed);

    const Objective& m_objective;
    ParameterRequest m_request;
    double m_scale;
    /// Whether state k is read, k = 0..T (from the objective's states_read(T)).
    std::vector<char> m_read;
    Trajectory m_states; ///< the thin copy: index, time, and x, v of the states read
    StateSeed m_seed; ///< scale * dJ, computed at the first seed() call, handed out per segment
    bool m_seeded = false;
    double m_value = 0;
    int m_stored_states = 0;
    size_t m_stored_bytes = 0;
};

} // namespace diffipc
