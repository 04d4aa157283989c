#pragma once
/// @file adjoint.hpp
/// The discrete adjoint of a recorded run (docs/math.md "Adjoint").
///
/// Step k solves g_k(x_k; x_{k-1}, x_{k-2}, v_{k-1}, ..., p) = 0 on the free dofs,
/// g_k the gradient of the incremental potential; prescribed dofs are
/// x_k = X + g_k. Backward from k = T: the state adjoints (dJ/dv_k, dJ/da_k)
/// are pushed into x_k and the history through the integrator's linear maps,
/// then H_k lambda_k = dJ/dx_k on the free dofs, H_k the true (unprojected)
/// Hessian at the converged state, and lambda_k carries the sensitivity to the
/// history (inertial target, start-of-step positions) and the parameters:
/// dJ/dp -= lambda_k^T dg_k/dp.

#include "adjoint/sensitivity.hpp"
#include "forward/simulation/simulator.hpp"

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace diffipc {

/// A gradient that cannot be computed (failed forward step, unsupported
/// configuration, singular adjoint system); no number is returned.
class AdjointError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

/// Timings and sizes of one backward sweep.
struct AdjointStatistics {
    double assembly_time = 0; ///< Hessians and parameter derivatives (s)
    double parameter_time = 0; ///< of which parameter derivatives, history and friction terms (s)
    double factorization_time = 0; ///< s
    double solve_time = 0; ///< triangular solves (s); in a GPU run the device's PCG solves
    /// The sweep's set-up and each step's problem (Simulator::step_problem: inertial target, forces,
    /// contact and friction data) (s)
    double setup_time = 0;
    long device_pcg_iterations = 0; ///< PCG iterations of the device's adjoint solves (GPU runs)
    double total_time = 0; ///< s
    int steps = 0; ///< adjoint systems solved
    /// Peak bytes of the adjoint state vectors dJ/dx_k, dJ/dv_k, dJ/da_k held at once
    /// (seeded states not yet swept, and the history a step pushes into).
    size_t peak_adjoint_bytes = 0;
};

/// @brief dJ/dp of an objective over the simulator's committed trajectory.
/// @param sim      a simulator whose run() committed every step of its scene
///                 (the potentials are reconfigured step by step; its trajectory is unchanged)
/// @param seed     dJ/dx_k, dJ/dv_k for k = 0..T and J's explicit partials
/// @param request  the parameter blocks to compute (nothing else is)
/// @param stats    optional timings
/// @throws AdjointError if the run failed or stopped early, if contact used the
///         adaptive barrier stiffness (differentiate with a fixed kappa), if a
///         friction step re-lagged within the step or was solved in sub-steps (time.adaptive),
///         or if an adjoint system is singular.
ParameterGradient adjoint_gradient(
    Simulator& sim, const StateSeed& seed, const ParameterRequest& request, AdjointStatistics* stats = nullptr);

/// @brief dJ_i/dp of several objectives over one run: the sweeps go backward together, so
/// each step's adjoint system is assembled and factorized once for all of them (one
/// factorization and m solves per step instead of m of each).
/// @param seeds  one seed per objective, as adjoint_gradient()'s
/// @param stats  optional: the sweeps' timings summed; `steps` counts every solve, and
///               peak_adjoint_bytes is the sum of the sweeps' peaks (an upper bound)
/// @return one gradient per seed, in order
/// @throws AdjointError as adjoint_gradient()
std::vector<ParameterGradient> adjoint_gradients(Simulator& sim, const std::vector<StateSeed>& seeds,
    const ParameterRequest& request, AdjointStatistics* stats = nullptr);

/// The backward sweep of adjoint_gradient() one step at a time, so that a
/// checkpointed gradient (adjoint/checkpointing.hpp) can recompute records
/// between steps. Use: add_seed() for each state before its step, step(k) for
/// k = T, T-1, ..., 1 in that order, then finish() once.
class AdjointSweep {
public:
    /// @param sim     as for adjoint_gradient(); its records may be thinned
    ///                (StepRecord::release_state()) as long as step(k) finds its own held
    /// @throws AdjointError as adjoint_gradient() for a run that cannot be differentiated
    AdjointSweep(Simulator& sim, const ParameterRequest& request);
    /// @brief A sweep over the same run that shares `share_with`'s step systems: when both step
    /// through k in turn (lockstep), step k's system is assembled and factorized once.
    /// Nothing else may change the simulator's step problem between them.
    /// @throws std::logic_error if share_with sweeps another simulator; AdjointError as above
    AdjointSweep(Simulator& sim, const ParameterRequest& request, const AdjointSweep& share_with);
    ~AdjointSweep();
    AdjointSweep(const AdjointSweep&) = delete;
    AdjointSweep& operator=(const AdjointSweep&) = delete;

    /// @brief Adds the seed's entries for states first..last (its other entries are
    /// not read) and its explicit partials (add those once in all).
    /// @param seed  T + 1 entries (adjoint_gradient()'s seed)
    /// @throws std::logic_error for a state whose step was already swept
    void add_seed(const StateSeed& seed, int first, int last);
    /// @brief Backward step k (1-based), the next one: T first. Needs the step-k
    /// problem (Simulator::step_problem(k)): the records of steps k - history() .. k
    /// hold their state. The adjoint vectors of state k are freed afterwards.
    /// @throws AdjointError for a singular or non-finite adjoint system
    void step(int k);
    /// @brief The initial state's part, after step(1); returns dJ/dp.
    ParameterGradient finish();
    /// The sweep's statistics so far.
    const AdjointStatistics& statistics() const;

private:
    struct Impl;
    std::unique_ptr<Impl> m;
};

} // namespace diffipc
