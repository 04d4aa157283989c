#pragma once
/// @file barrier.hpp
/// IPC's clamped log barrier
/// on squared distances (Li et al. 2020, eq. 6, in IPC Toolkit's squared-distance form). With a
/// minimum separation dmin it acts on z = s - dmin^2 with activation shat = (2 dmin + dhat) dhat,
/// i.e. for dmin < d < dmin + dhat. (The adaptive-stiffness rules stay on the host.)

#include "forward/kernels/vec3.hpp"

namespace diffipc::kernels {

/// @brief b(z) = -(z - shat)^2 ln(z / shat) for 0 < z < shat, 0 for z >= shat, +inf for z <= 0.
/// @param z    squared distance minus dmin^2, m^2
/// @param shat activation value, m^2
template <class T> DIFFIPC_HD inline T barrier(T z, T shat)
{
    if (z <= 0)
        return infinity<T>();
    if (z >= shat)
        return 0;
    const T r = z - shat;
    return -r * r * log(z / shat);
}

/// @brief db/dz = -2 (z - shat) ln(z/shat) - (z - shat)^2 / z on (0, shat), else 0.
template <class T> DIFFIPC_HD inline T barrier_first_derivative(T z, T shat)
{
    if (z <= 0 || z >= shat)
        return 0;
    const T r = z - shat;
    return -2 * r * log(z / shat) - r * r / z;
}

/// @brief d2b/dz2 = -2 ln(z/shat) - 4 (z - shat)/z + (z - shat)^2 / z^2 on (0, shat), else 0.
template <class T> DIFFIPC_HD inline T barrier_second_derivative(T z, T shat)
{
    if (z <= 0 || z >= shat)
        return 0;
    const T r = z - shat;
    return -2 * log(z / shat) - 4 * r / z + r * r / (z * z);
}

/// The barrier's activation value for dhat and dmin: (2 dmin + dhat) dhat (m^2).
template <class T> DIFFIPC_HD inline T barrier_activation(T dhat, T dmin) { return (2 * dmin + dhat) * dhat; }

} // namespace diffipc::kernels
