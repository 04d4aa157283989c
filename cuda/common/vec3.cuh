#pragma once
/// @file vec3.cuh
/// A 3-vector of doubles for code that runs on the host and on the device
/// (no Eigen on the GPU machine). Every operation is written so that it rounds
/// exactly like the Eigen::Vector3d expression it replaces in the CPU code
/// (same operations in the same order, one rounding each): a sum of three terms
/// is ((a + b) + c), as Eigen's reductions of a 3-vector evaluate it, and the
/// cross product is Eigen's formula. That, and compiling device code without
/// fused multiply-adds, is what makes the GPU's results the CPU's bit for bit
/// (see cuda/ccd/ccd.cuh).
///
/// Headers under cuda/ that end in .cuh compile with nvcc and with a plain C++
/// compiler (then DIFFIPC_HD is empty), so that the CPU tests call the very
/// functions the kernels run.

#include <cmath>

#ifndef DIFFIPC_HD
#if defined(__CUDACC__)
#define DIFFIPC_HD __host__ __device__
#else
#define DIFFIPC_HD
#endif
#endif

namespace diffipc {
namespace gpu {

    struct vec3 {
        double x = 0, y = 0, z = 0;

        DIFFIPC_HD vec3() { }
        DIFFIPC_HD vec3(double x_, double y_, double z_)
            : x(x_)
            , y(y_)
            , z(z_)
        {
        }
        /// From three consecutive doubles (x, y, z).
        DIFFIPC_HD static vec3 load(const double* p) { return vec3(p[0], p[1], p[2]); }
    };

    DIFFIPC_HD inline vec3 operator+(const vec3& a, const vec3& b) { return vec3(a.x + b.x, a.y + b.y, a.z + b.z); }
    DIFFIPC_HD inline vec3 operator-(const vec3& a, const vec3& b) { return vec3(a.x - b.x, a.y - b.y, a.z - b.z); }
    DIFFIPC_HD inline vec3 operator*(double s, const vec3& a) { return vec3(s * a.x, s * a.y, s * a.z); }
    DIFFIPC_HD inline vec3 operator/(const vec3& a, double s) { return vec3(a.x / s, a.y / s, a.z / s); }

    DIFFIPC_HD inline double dot(const vec3& a, const vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
    DIFFIPC_HD inline vec3 cross(const vec3& a, const vec3& b)
    {
        return vec3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
    }
    DIFFIPC_HD inline double squared_norm(const vec3& a) { return dot(a, a); }
    /// sqrt is correctly rounded on both sides (IEEE 754; nvcc's default -prec-sqrt=true).
    DIFFIPC_HD inline double norm(const vec3& a) { return sqrt(squared_norm(a)); }

    /// std::min and std::max, NaN behaviour included: the first argument unless the second compares smaller (larger).
    DIFFIPC_HD inline double min_of(double a, double b) { return b < a ? b : a; }
    DIFFIPC_HD inline double max_of(double a, double b) { return a < b ? b : a; }

    /// max(|x|, |y|, |z|) (Eigen's cwiseAbs().maxCoeff() for finite coordinates).
    DIFFIPC_HD inline double max_abs(const vec3& a) { return max_of(max_of(fabs(a.x), fabs(a.y)), fabs(a.z)); }

    /// True for finite x: x - x is 0 then, and NaN for an infinity or a NaN (no -ffast-math anywhere).
    DIFFIPC_HD inline bool is_finite(double x) { return x - x == 0; }
    DIFFIPC_HD inline bool all_finite(const vec3& a) { return is_finite(a.x) && is_finite(a.y) && is_finite(a.z); }

} // namespace gpu
} // namespace diffipc
