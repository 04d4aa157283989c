#include "forward/contact/barrier.hpp"

#include "forward/kernels/barrier.hpp"

#include <algorithm>
#include <cmath>

namespace diffipc {

double barrier(double s, double shat) { return kernels::barrier(s, shat); }

double barrier_first_derivative(double s, double shat) { return kernels::barrier_first_derivative(s, shat); }

double barrier_second_derivative(double s, double shat) { return kernels::barrier_second_derivative(s, shat); }

double barrier_stiffness_min(double bbox_diagonal, double reference_mass, double dhat, double dmin)
{
    const double d0 = std::pow(1e-8 * bbox_diagonal + dmin, 2);
    const double shat = barrier_activation(dhat, dmin);
    const double s = d0 - dmin * dmin;
    const double b2 = barrier_second_derivative(s, shat);
    if (!(b2 > 0))
        return 0.0; // dhat at or below 1e-8 L: no lower bound exists; callers reject 0
    return 1e11 * reference_mass / (4 * d0 * b2);
}

double initial_barrier_stiffness(double grad_energy_dot_barrier, double grad_barrier_squared, double kappa_min)
{
    if (!(grad_barrier_squared > 0))
        return kappa_min;
    const double kappa = -grad_energy_dot_barrier / grad_barrier_squared;
    return std::clamp(kappa, kappa_min, 100 * kappa_min);
}

double update_barrier_stiffness(double previous_min_distance_squared, double min_distance_squared, double kappa,
    double kappa_max, double bbox_diagonal, double dmin)
{
    const double eps = std::pow(1e-9 * (bbox_diagonal + dmin), 2);
    if (previous_min_distance_squared < eps && min_distance_squared < eps
        && min_distance_squared < previous_min_distance_squared)
        return std::min(2 * kappa, kappa_max);
    return kappa;
}

} // namespace diffipc
