#pragma once
/// @file reduction.hpp
/// Deterministic sums and dot products of device vectors. The summation order is a fixed
/// tree that depends only on the length n, never on the scheduling of threads or blocks:
/// thread t of block b (256 threads, B = min(ceil(n / 256), 256) blocks) adds the terms
/// k = b 256 + t + m (256 B), m = 0, 1, ..., in increasing m; each block halves its 256
/// values pairwise (s[t] += s[t + h], h = 128, 64, ..., 1); one block then reduces the B block
/// sums the same way. No atomics: two calls on the same data give bitwise equal results.
/// Host functions on device pointers; they run on the default stream and do not synchronize
/// (the result stays on the device until the caller copies it).

#include <cstddef>

namespace diffipc::gpu {

/// Scratch doubles a reduction needs (per reduced quantity).
constexpr int REDUCTION_PARTIALS = 256;

/// @brief *d_result = sum_{k < n} d_values[k].
/// @param d_partials device scratch of REDUCTION_PARTIALS doubles
void deterministic_sum(const double* d_values, size_t n, double* d_partials, double* d_result);

/// @brief *d_result = sum_{k < n} d_a[k] d_b[k].
/// @param d_partials device scratch of REDUCTION_PARTIALS doubles
void deterministic_dot(const double* d_a, const double* d_b, size_t n, double* d_partials, double* d_result);

/// @brief d_result[0] = a . b and d_result[1] = c . d in one pass (vectors of length n).
/// @param d_partials device scratch of 2 REDUCTION_PARTIALS doubles
void deterministic_dot2(const double* d_a, const double* d_b, const double* d_c, const double* d_d, size_t n,
    double* d_partials, double* d_result);

} // namespace diffipc::gpu
