#pragma once
/// @file objective.hpp
/// Objectives J(x_0..x_T, v_0..v_T; p): scalar functionals of a recorded run and
/// of the simulation's canonical parameters p (adjoint/sensitivity.hpp). Each
/// gives its value and hands the adjoint its derivatives with respect to every
/// state and its explicit partial derivatives with respect to the parameters.
///
/// State k: k = 0 is (trajectory.initial_positions, initial_velocities), k >= 1 is
/// (trajectory.steps[k-1].positions, .velocities); all #V*dim, flattened
/// vertex-major, deformed positions x = X + u (m) and velocities (m/s). The
/// parameters are read from the simulator: rest positions X =
/// flatten(sim.mesh().rest_positions), per-element Lame parameters
/// sim.elastic().mu(), .lambda() and densities sim.inertia().density().

#include "adjoint/sensitivity.hpp"
#include "forward/common/error.hpp"
#include "forward/simulation/simulator.hpp"

#include <string>
#include <vector>

namespace diffipc {

/// An objective that is not defined at this run (a max_p of a negative value, a non-integer
/// power of one): an InputError about the field "objective" (the CLI's exit 1, Python's ValueError).
class ObjectiveDomainError : public InputError {
public:
    explicit ObjectiveDomainError(const std::string& message)
        : InputError("objective", message)
    {
    }
};

class Objective {
public:
    virtual ~Objective() = default;
    virtual std::string name() const = 0;
    /// J for the simulator's parameters (mesh rest positions, elastic mu/lambda, densities) and the given trajectory.
    virtual double value(const Simulator& sim, const Trajectory& trajectory) const = 0;
    /// Adds scale * dJ/dx_k, scale * dJ/dv_k (k = 0..T) and scale * the explicit partials of J with respect to the
    /// requested canonical parameter blocks into `seed` (already resized for T = trajectory.steps.size()).
    virtual void add_gradient(const Simulator& sim, const Trajectory& trajectory, const ParameterRequest& request,
        double scale, StateSeed& seed) const = 0;
    /// @brief The states k whose positions or velocities value() and add_gradient() read (any order;
    /// the times t_k are always readable). A checkpointed gradient keeps only these for the objective
    /// (objectives/streamed.hpp), so a declaration must not miss one: reading an undeclared state there
    /// throws std::logic_error.
    /// @param steps T
    /// @return by default every state 0..T
    virtual std::vector<int> states_read(int steps) const;
    /// @brief The absolute round-off of value(): a value in [-round_off, 0) is zero up to
    /// round-off (docs/objectives.md). By default 0 (no allowance).
    virtual double round_off(const Simulator& /*sim*/, const Trajectory& /*trajectory*/) const { return 0.0; }
};

/// @name The states of a trajectory by index k = 0..T.
/// @{
inline int num_steps(const Trajectory& trajectory) { return int(trajectory.steps.size()); }
/// x_k (#V*dim, m). @throws std::out_of_range for k outside 0..T; std::logic_error for a state
/// that the trajectory does not hold (a record released by checkpointing).
const VectorXd& state_positions(const Trajectory& trajectory, int k);
/// v_k (#V*dim, m/s). @throws as state_positions().
const VectorXd& state_velocities(const Trajectory& trajectory, int k);
/// t_k (s): trajectory.initial_time for k = 0, steps[k-1].time otherwise.
double state_time(const Trajectory& trajectory, int k);
/// @}

/// @brief The gradient block to add into: `block` itself, set to zeros of size n if it is empty.
/// @throws std::logic_error if it is allocated with another size.
VectorXd& gradient_block(VectorXd& block, Index n);

/// @brief Indices of the elements of body `body` (all elements for body < 0).
/// @throws std::out_of_range if the mesh has no element of a body index >= 0.
std::vector<Index> body_elements(const Mesh& mesh, int body);

} // namespace diffipc
