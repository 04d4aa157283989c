#pragma once
/// @file vec3.hpp
/// A 3-vector over a scalar type for the per-element and per-pair physics that the CPU path and
/// the GPU path share (forward/kernels/). Every operation rounds exactly like the
/// Eigen::Vector3d expression it replaced (same operations in the same order, one rounding each):
/// a sum of three terms is ((a + b) + c), as Eigen's reductions of a 3-vector evaluate it, and
/// the cross product is Eigen's formula. That, and compiling device code without fused
/// multiply-adds, is what makes the GPU's results the CPU's bit for bit where the operations are
/// IEEE-exact (see forward/kernels/ccd/ccd.hpp).
///
/// The kernels are templates over the scalar T (double today) so that the same code can be
/// evaluated with dual numbers (directional third derivatives); `vec3` is Vec3<double>.

#include "forward/kernels/host_device.hpp"

namespace diffipc::kernels {

template <class T> struct Vec3 {
    T x = 0, y = 0, z = 0;

    DIFFIPC_HD Vec3() { }
    DIFFIPC_HD Vec3(T x_, T y_, T z_)
        : x(x_)
        , y(y_)
        , z(z_)
    {
    }
    /// From three consecutive scalars (x, y, z).
    DIFFIPC_HD static Vec3 load(const T* p) { return Vec3(p[0], p[1], p[2]); }
};

using vec3 = Vec3<double>;

template <class T> DIFFIPC_HD inline Vec3<T> operator+(const Vec3<T>& a, const Vec3<T>& b)
{
    return Vec3<T>(a.x + b.x, a.y + b.y, a.z + b.z);
}
template <class T> DIFFIPC_HD inline Vec3<T> operator-(const Vec3<T>& a, const Vec3<T>& b)
{
    return Vec3<T>(a.x - b.x, a.y - b.y, a.z - b.z);
}
template <class S, class T> DIFFIPC_HD inline Vec3<T> operator*(const S& s, const Vec3<T>& a)
{
    return Vec3<T>(s * a.x, s * a.y, s * a.z);
}
template <class T, class S> DIFFIPC_HD inline Vec3<T> operator/(const Vec3<T>& a, const S& s)
{
    return Vec3<T>(a.x / s, a.y / s, a.z / s);
}

template <class T> DIFFIPC_HD inline T dot(const Vec3<T>& a, const Vec3<T>& b)
{
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
template <class T> DIFFIPC_HD inline Vec3<T> cross(const Vec3<T>& a, const Vec3<T>& b)
{
    return Vec3<T>(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
template <class T> DIFFIPC_HD inline T squared_norm(const Vec3<T>& a) { return dot(a, a); }
/// sqrt is correctly rounded on both sides (IEEE 754; nvcc's default -prec-sqrt=true).
template <class T> DIFFIPC_HD inline T norm(const Vec3<T>& a) { return sqrt(squared_norm(a)); }

/// max(|x|, |y|, |z|) (Eigen's cwiseAbs().maxCoeff() for finite coordinates).
template <class T> DIFFIPC_HD inline T max_abs(const Vec3<T>& a)
{
    return max_of(max_of(fabs(a.x), fabs(a.y)), fabs(a.z));
}
template <class T> DIFFIPC_HD inline bool all_finite(const Vec3<T>& a)
{
    return is_finite(a.x) && is_finite(a.y) && is_finite(a.z);
}

/// Component i (0, 1, 2) of v.
template <class T> DIFFIPC_HD inline T component(const Vec3<T>& v, int i) { return i == 0 ? v.x : i == 1 ? v.y : v.z; }

/// Writes v into g[0..2].
template <class T> DIFFIPC_HD inline void store(const Vec3<T>& v, T* g)
{
    g[0] = v.x;
    g[1] = v.y;
    g[2] = v.z;
}

} // namespace diffipc::kernels
