#pragma once
/// @file state_functional.hpp
/// Per-state functionals f_k = f(x_k, v_k, t_k; p): quantities of one state
/// (a stress norm, an energy, a volume) that a TimeAggregation turns into an
/// Objective over the whole run.

#include "adjoint/sensitivity.hpp"
#include "forward/simulation/simulator.hpp"

#include <string>

namespace diffipc {

/// One state of a run, as a per-state functional sees it.
struct StateRef {
    int step = 0; ///< k (0: the initial state)
    double time = 0; ///< t_k (s)
    const VectorXd& positions; ///< x_k, #V*dim deformed positions (m), flattened vertex-major
    const VectorXd& velocities; ///< v_k, #V*dim (m/s)
};

class StateFunctional {
public:
    virtual ~StateFunctional() = default;
    virtual std::string name() const = 0;
    /// @brief f(x_k, v_k, t_k; p) for the simulator's parameters.
    virtual double value(const Simulator& sim, const StateRef& state) const = 0;
    /// @brief Adds scale * df/dx_k into d_positions, scale * df/dv_k into d_velocities and
    /// scale * the explicit partials df/dp of the blocks `request` asks for into `partials`.
    /// @param d_positions, d_velocities #V*dim, or empty (read as zero): an implementation
    ///        allocates one (gradient_block()) only when it adds to it
    virtual void add_gradient(const Simulator& sim, const StateRef& state, const ParameterRequest& request,
        double scale, VectorXd& d_positions, VectorXd& d_velocities, ParameterGradient& partials) const = 0;
    /// @brief The absolute round-off of value() at this state: a value in [-round_off, 0) is
    /// zero up to round-off (docs/objectives.md, "Values within round-off of zero"). Zero for a
    /// functional whose evaluation cannot come out negative when its exact value is not.
    virtual double round_off(const Simulator& /*sim*/, const StateRef& /*state*/) const { return 0.0; }
};

} // namespace diffipc
