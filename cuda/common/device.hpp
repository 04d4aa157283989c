#pragma once
/// @file device.hpp
/// Whether a GPU is there, and CUDA errors as exceptions. Host code; compiles
/// with nvcc and with a plain C++ compiler (it needs only the CUDA runtime's
/// C header).

#include <cuda_runtime_api.h>

#include <string>

namespace diffipc {
namespace gpu {

    /// @brief True when the CUDA runtime works and sees at least one device
    /// (cudaGetDeviceCount succeeds with a count > 0). False on a machine with
    /// nvcc but no GPU or no driver; never throws.
    bool cuda_device_available();

    /// @brief One line about device 0 for logs: its name, compute capability, multiprocessors and the driver's
    /// and runtime's CUDA versions; or "no CUDA device: <the runtime's reason>".
    std::string cuda_device_description();

    /// @brief Throws std::runtime_error("no CUDA device: <what> needs a GPU (<the runtime's reason>)") unless
    /// cuda_device_available().
    void require_cuda_device(const std::string& what);

    /// @brief Throws std::runtime_error naming the call and the CUDA error unless error == cudaSuccess.
    /// @param error  the status a CUDA runtime call returned
    /// @param what   the call, for the message (e.g. "cudaMemcpy of the CCD queries")
    void check_cuda(cudaError_t error, const char* what);

} // namespace gpu
} // namespace diffipc
