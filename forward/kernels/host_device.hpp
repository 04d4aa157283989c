#pragma once
/// @file host_device.hpp
/// What makes a header of forward/kernels/ compile for the host and for the device: the
/// DIFFIPC_HD qualifier (__host__ __device__ under nvcc, nothing for a plain C++ compiler) and
/// the few scalar helpers whose standard-library versions are not device functions. The headers
/// under forward/kernels/ use no Eigen and no standard containers, only these, <cmath> and
/// fixed-size arrays; the CPU path reaches them through Eigen adapters (forward/contact/distance,
/// forward/materials, ...), the GPU path from its .cu files (cuda/).

#include <cmath>
#include <math.h> // ::log, ::sqrt, ::fabs: the names the device compiler provides

#ifndef DIFFIPC_HD
#if defined(__CUDACC__)
#define DIFFIPC_HD __host__ __device__
#else
#define DIFFIPC_HD
#endif
#endif

namespace diffipc::kernels {

/// std::min and std::max, NaN behaviour included: the first argument unless the second compares smaller (larger).
template <class T> DIFFIPC_HD inline T min_of(T a, T b) { return b < a ? b : a; }
template <class T> DIFFIPC_HD inline T max_of(T a, T b) { return a < b ? b : a; }

/// True for finite x: x - x is 0 then, and NaN for an infinity or a NaN (no -ffast-math anywhere).
template <class T> DIFFIPC_HD inline bool is_finite(T x) { return x - x == 0; }

/// T in a parameter that must not take part in deducing T (an optional output that may be nullptr).
template <class T> struct NonDeduced {
    using type = T;
};
template <class T> using non_deduced = typename NonDeduced<T>::type;

/// Whether T is double: what only the plain evaluation does (a PSD projection) is skipped for other scalars.
template <class T> inline constexpr bool is_double = false;
template <> inline constexpr bool is_double<double> = true;

/// +infinity of T (HUGE_VAL is a constant expression on both sides).
template <class T> DIFFIPC_HD inline T infinity() { return T(HUGE_VAL); }

} // namespace diffipc::kernels
