#pragma once
/// @file device_potential.hpp
/// A potential evaluated on the GPU (DeviceElasticMesh, DeviceBarrier): the device-resident
/// energy, gradient and Hessian each potential implements, and the host conveniences built on
/// them once here (x copied up, the result copied back), for tests and small callers.
///
/// Layouts: x and gradients num_dofs() doubles, flattened vertex-major (xyzxyz); Hessians in a
/// DeviceBsrMatrix of dim by dim blocks from the potential's make_hessian_matrix().

#include "cuda/linalg/bsr_matrix.hpp"
#include "cuda/linalg/device_array.hpp"

#include <vector>

namespace diffipc::gpu {

class DevicePotential {
public:
    DevicePotential() = default;
    DevicePotential(DevicePotential&&) = default; // device buffers move, never copy
    DevicePotential& operator=(DevicePotential&&) = default;
    virtual ~DevicePotential() = default;

    virtual int num_dofs() const = 0;
    /// @name Device-resident evaluation: d_x and d_g are num_dofs() doubles in GPU memory.
    /// @{
    /// @brief The potential's value at x (J). Copies one double back.
    virtual double energy_device(const double* d_x) const = 0;
    /// @brief d_g += weight * gradient at x. Asynchronous.
    virtual void add_gradient_device(const double* d_x, double weight, double* d_g) const = 0;
    /// @brief H += weight * Hessian at x, projected to PSD as the potential defines it if `project`.
    virtual void add_hessian_device(const double* d_x, double weight, bool project, DeviceBsrMatrix& H) const = 0;
    /// @}
    /// @brief A zero matrix on the potential's Hessian pattern, to assemble into.
    virtual DeviceBsrMatrix make_hessian_matrix() const = 0;

    /// @name Host convenience: x is copied to the GPU first.
    /// @{
    double energy(const std::vector<double>& x) const;
    /// @brief weight * the gradient, num_dofs() doubles.
    std::vector<double> gradient(const std::vector<double>& x, double weight = 1.0) const;
    /// @brief Assembles weight * the (projected) Hessian into a matrix this object holds on a fresh
    /// make_hessian_matrix(), and returns it (valid until the next call).
    const DeviceBsrMatrix& hessian_bsr(const std::vector<double>& x, bool project, double weight = 1.0) const;
    /// @}

protected:
    /// The potential's name, for error messages.
    virtual const char* potential_name() const = 0;

private:
    void upload(const std::vector<double>& x) const;
    mutable DeviceArray<double> m_x, m_g;
    mutable DeviceBsrMatrix m_hessian;
};

} // namespace diffipc::gpu
