#pragma once
/// @file integrator.hpp
/// Time integrators as incremental potentials (docs/math.md):
/// E(x) = 1/2 (x - x~)^T M (x - x~) + c h^2 [Psi(x) - f^T (x - X)].
/// Each integrator gives x~ and c h^2 from its history, and the velocity (and
/// acceleration) at a new position. Static drops inertia (weight 1 on the rest).

#include "forward/common/types.hpp"
#include "forward/scene/scene.hpp"

#include <memory>

namespace diffipc {

/// Step k of a scheme as linear maps of the states of steps k-1 and k-2
/// (index j of each array: the state k-j; entries for j = 0 only in vx, ax):
///   x~_k = sum_{j=1,2} tx_j x_{k-j} + tv_j v_{k-j} + ta_j a_{k-j},
///   v_k  = vx_0 x_k + sum_{j=1,2} (vx_j x_{k-j} + vv_j v_{k-j} + va_j a_{k-j}),
///   a_k  = ax_0 x_k + sum_{j=1,2} (ax_j x_{k-j} + av_j v_{k-j} + aa_j a_{k-j}).
/// The adjoint runs these maps backward.
struct StepScheme {
    bool inertia = true; ///< false: static (no inertial term)
    double weight = 1; ///< c h^2 of the non-inertial potentials
    double tx[3] = { 0, 0, 0 }, tv[3] = { 0, 0, 0 }, ta[3] = { 0, 0, 0 };
    double vx[3] = { 0, 0, 0 }, vv[3] = { 0, 0, 0 }, va[3] = { 0, 0, 0 };
    double ax[3] = { 0, 0, 0 }, av[3] = { 0, 0, 0 }, aa[3] = { 0, 0, 0 };
};

class TimeIntegrator {
public:
    virtual ~TimeIntegrator() = default;
    static std::unique_ptr<TimeIntegrator> create(IntegratorType type, double dt);

    virtual IntegratorType type() const = 0;
    bool dynamic() const { return type() != IntegratorType::STATIC; }
    double dt() const { return m_dt; }

    /// @brief Sets the state at t0: positions, velocities, accelerations (flattened).
    virtual void initialize(const VectorXd& x0, const VectorXd& v0, const VectorXd& a0);
    /// Inertial target x~ for the next step.
    virtual VectorXd inertial_target() const = 0;
    /// Weight c h^2 of the non-inertial potentials (1 for static).
    virtual double potential_weight() const = 0;
    /// @brief Velocity and acceleration that the scheme assigns to x_next.
    virtual void update(const VectorXd& x_next, VectorXd& v_next, VectorXd& a_next) const = 0;
    /// @brief The linear maps of step k (1-based), independent of the state.
    virtual StepScheme scheme(int k) const = 0;
    /// @brief Shifts the history after a committed step.
    virtual void commit(const VectorXd& x_next, const VectorXd& v_next, const VectorXd& a_next);
    /// Number of committed states a step reads: 2 for BDF2 (x_{n-1}, v_{n-1} too), 1 otherwise.
    virtual int history() const { return 1; }
    /// @brief Puts the integrator back at committed step `steps` (a restart from a
    /// checkpoint): x, v, a of that step and, for history() == 2, x and v of the
    /// step before (ignored otherwise). The next step is then bit-identical to
    /// the one taken from there the first time.
    void restore(int steps, const VectorXd& x, const VectorXd& v, const VectorXd& a, const VectorXd& x_prev,
        const VectorXd& v_prev);
    /// Steps committed since initialize() (or the step restore() put it at).
    int steps() const { return m_steps; }

    const VectorXd& positions() const { return m_x; }
    const VectorXd& velocities() const { return m_v; }
    const VectorXd& accelerations() const { return m_a; }

protected:
    explicit TimeIntegrator(double dt)
        : m_dt(dt)
    {
    }
    double m_dt;
    VectorXd m_x, m_v, m_a;
    VectorXd m_x_prev, m_v_prev;
    int m_steps = 0;
};

} // namespace diffipc
