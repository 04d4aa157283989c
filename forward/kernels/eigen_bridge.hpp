#pragma once
/// @file eigen_bridge.hpp
/// Host only: how the CPU path's Eigen types meet the kernels of forward/kernels/. The kernels
/// take Vec3 and write derivatives into row-major arrays; the CPU's adapters
/// (forward/contact/distance/, ...) convert with these, so that every formula exists once.

#include "forward/kernels/vec3.hpp"

#include <Eigen/Core>

namespace diffipc::kernels {

inline vec3 to_vec3(const Eigen::Vector3d& v) { return vec3(v.x(), v.y(), v.z()); }

inline Eigen::Vector3d to_eigen(const vec3& v) { return Eigen::Vector3d(v.x, v.y, v.z); }

/// @brief Runs `write(double* out)` on an N-vector and returns it.
template <int N, class Writer> Eigen::Matrix<double, N, 1> kernel_vector(Writer&& write)
{
    Eigen::Matrix<double, N, 1> out;
    write(out.data());
    return out;
}

/// @brief Runs `write(double* out)` on a row-major N x N matrix (the kernels' layout) and returns it.
template <int N, class Writer> Eigen::Matrix<double, N, N> kernel_matrix(Writer&& write)
{
    Eigen::Matrix<double, N, N, Eigen::RowMajor> out;
    write(out.data());
    return out;
}

} // namespace diffipc::kernels
