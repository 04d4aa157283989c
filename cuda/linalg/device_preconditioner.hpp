#pragma once
/// @file device_preconditioner.hpp
/// A preconditioner DevicePCG (device_pcg.hpp) can take instead of its own block-Jacobi: z = M r
/// for a symmetric positive definite M, applied on the device. DeviceAmg (device_amg.hpp) is one.
/// Host API (plain C++).

namespace diffipc::gpu {

class DevicePreconditioner {
public:
    virtual ~DevicePreconditioner() = default;
    /// Rows of the vectors it applies to.
    virtual int size() const = 0;
    /// @brief d_z = M d_r (device vectors of size() doubles, vertex-major). r's fixed entries are 0 and
    /// z's are left 0. Deterministic; asynchronous (default stream).
    virtual void apply(const double* d_r, double* d_z) const = 0;
};

} // namespace diffipc::gpu
