#pragma once
/// @file barrier.hpp
/// IPC's clamped log barrier on squared distances and its adaptive stiffness
/// (Li et al. 2020, "Incremental Potential Contact", eq. 6 and Appendix;
/// the squared-distance form and the stiffness rule follow IPC Toolkit, see
/// docs/math.md "Contact"). With a minimum separation dmin the barrier acts on
/// s - dmin^2 with activation shat = (2 dmin + dhat) dhat, i.e. it is active
/// for dmin < d < dmin + dhat.

#include "forward/kernels/barrier.hpp"

namespace diffipc {

/// @brief b(s) = -(s - shat)^2 ln(s / shat) for 0 < s < shat, 0 for s >= shat, +inf for s <= 0.
/// @param s    squared distance (minus dmin^2), m^2
/// @param shat activation value, m^2
double barrier(double s, double shat);
/// @brief db/ds = -2 (s - shat) ln(s/shat) - (s - shat)^2 / s on (0, shat), else 0.
double barrier_first_derivative(double s, double shat);
/// @brief d2b/ds2 = -2 ln(s/shat) - 4 (s - shat)/s + (s - shat)^2 / s^2 on (0, shat), else 0.
double barrier_second_derivative(double s, double shat);

/// The barrier's activation value for dhat and dmin: (2 dmin + dhat) dhat.
inline double barrier_activation(double dhat, double dmin) { return kernels::barrier_activation(dhat, dmin); }

/// @brief Lower bound of the adaptive barrier stiffness (IPC Toolkit):
/// kappa_min = 1e11 m / (4 d0 b''(d0 - dmin^2)), d0 = (1e-8 L + dmin)^2;
/// 0 when d0 is outside the barrier's support (dhat <= 1e-8 L).
/// @param bbox_diagonal    L, diagonal of the scene's bounding box (m)
/// @param reference_mass   per-vertex stiffness reference: the average lumped
///                         nodal mass divided by the potential weight c h^2
///                         for dynamics (kg/s^2 = N/m); for static solves a
///                         nodal elastic stiffness (docs/math.md)
double barrier_stiffness_min(double bbox_diagonal, double reference_mass, double dhat, double dmin);

/// @brief Initial adaptive stiffness: the kappa that best balances the other
/// forces, -(grad B . grad E) / |grad B|^2, clamped to [kappa_min, 100 kappa_min]
/// (kappa_min if grad B = 0).
/// @param grad_energy_dot_barrier grad B . grad E (E: the incremental potential without the barrier, per unit weight)
/// @param grad_barrier_squared   |grad B|^2
double initial_barrier_stiffness(double grad_energy_dot_barrier, double grad_barrier_squared, double kappa_min);

/// @brief IPC's stiffness update after a Newton iteration: if the previous and
/// current minimum squared distances are both below eps = (1e-9 (L + dmin))^2
/// and the distance is decreasing, kappa doubles (capped at kappa_max).
double update_barrier_stiffness(double previous_min_distance_squared, double min_distance_squared, double kappa,
    double kappa_max, double bbox_diagonal, double dmin);

} // namespace diffipc
