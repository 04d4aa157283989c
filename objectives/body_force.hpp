#pragma once
/// @file body_force.hpp
/// The force that holds up (or pushes) one body, from its discrete momentum balance: what an
/// accelerometer on a falling object, or a load cell under it, measures. A cushion's drop test
/// judges the peak of this force on the protected object (issue 15).

#include "objectives/objective.hpp"
#include "objectives/time_aggregation.hpp"

namespace diffipc {

/// @brief Per step k >= 1, with s the indicator of body b's dofs along axis a,
///
///     F_k = s^T M (v_k - v_{k-1}) / (t_k - t_{k-1}) - g_a sum_{v in b} m_v   (N, per metre of depth in 2D),
///
/// the rate of the body's momentum less its weight. Implicit Euler's step satisfies
/// M (v_k - v_{k-1}) / h = f_ext(t_k) - grad(Psi + B + D)(x_k) on free dofs; over a whole body the
/// elastic forces cancel, so F_k is exactly the contact, friction and traction force on the body
/// at t_k (with another integrator, the momentum difference is still what F_k is). Aggregated:
/// FINAL (F_T), SUM, or MAX_P: (sum_k max(F_k, 0)^p)^(1/p), a smooth maximum of the force along
/// +axis (forces toward -axis count as 0). Gradient: dF_k/dv_k = M s / h = -dF_k/dv_{k-1};
/// explicit partials through the masses (rest positions and density).
class BodyForce : public Objective {
public:
    /// @param body b (>= 0); @param axis a; @param p MAX_P's exponent (>= 1)
    BodyForce(int body, int axis, TimeMode mode, double p = 8);

    std::string name() const override;
    double value(const Simulator& sim, const Trajectory& trajectory) const override;
    void add_gradient(const Simulator& sim, const Trajectory& trajectory, const ParameterRequest& request, double scale,
        StateSeed& seed) const override;

    /// F_k for k = 1..T (entry k - 1).
    VectorXd forces(const Simulator& sim, const Trajectory& trajectory) const;

private:
    /// s (#V*dim) for the simulator's mesh.
    VectorXd indicator(const Simulator& sim) const;
    /// (v_k - v_{k-1}) / h_k - g (#V*dim): F_k = s^T M delta_k.
    VectorXd delta(const Simulator& sim, const Trajectory& trajectory, int k) const;
    /// dJ/dF_k for k = 1..T.
    VectorXd weights(const VectorXd& F) const;

    int m_body, m_axis;
    TimeMode m_mode;
    double m_p;
};

} // namespace diffipc
