#pragma once
/// @file point_line.cuh
/// Host and device port of forward/contact/distance/point_line: the squared distance from a
/// point to the infinite line through two points, with gradient and Hessian. Derivatives are
/// vertex-major in argument order (p, e0, e1), xyz per vertex; Hessians row-major.

#include "cuda/contact/distance/distance_kernels.cuh"

namespace diffipc::gpu {

// Kernel variables r = p - e0, e = e1 - e0: plus vertices (p, e1), minus e0.

/// @brief \f$ |(e_0 - p) \times (e_1 - p)|^2 / |e_1 - e_0|^2 \f$ (m^2); requires e1 != e0.
DIFFIPC_HD inline double point_line_distance(const vec3& p, const vec3& e0, const vec3& e1)
{
    return distance_kernels::point_line(p - e0, e1 - e0, nullptr, nullptr);
}

/// @brief Gradient of point_line_distance. @param g out: 9 (d/dp, d/de0, d/de1), m
DIFFIPC_HD inline void point_line_distance_gradient(const vec3& p, const vec3& e0, const vec3& e1, double* g)
{
    double k[6];
    distance_kernels::point_line(p - e0, e1 - e0, k, nullptr);
    const int plus[2] = { 0, 2 };
    distance_kernels::pull_back_gradient<2>(k, plus, 1, g);
}

/// @brief Hessian of point_line_distance. @param H out: 9 x 9 row-major, ordered (p, e0, e1)
DIFFIPC_HD inline void point_line_distance_hessian(const vec3& p, const vec3& e0, const vec3& e1, double* H)
{
    double k[36];
    distance_kernels::point_line(p - e0, e1 - e0, nullptr, k);
    const int plus[2] = { 0, 2 };
    distance_kernels::pull_back_hessian<2>(k, plus, 1, H);
}

} // namespace diffipc::gpu
