#include "cuda/common/device.hpp"

#include <cuda_runtime.h>

#include <stdexcept>
#include <string>

namespace diffipc {
namespace gpu {

    namespace {

        /// cudaGetDeviceCount's answer: the count, or 0 and the reason.
        int device_count(std::string* reason)
        {
            int count = 0;
            const cudaError_t error = cudaGetDeviceCount(&count);
            if (error != cudaSuccess) {
                cudaGetLastError(); // the failure is not sticky: clear it for later calls
                if (reason)
                    *reason = std::string(cudaGetErrorName(error)) + ": " + cudaGetErrorString(error);
                return 0;
            }
            if (count <= 0 && reason)
                *reason = "cudaGetDeviceCount found no device";
            return count;
        }

    } // namespace

    bool cuda_device_available() { return device_count(nullptr) > 0; }

    std::string cuda_device_description()
    {
        std::string reason;
        if (device_count(&reason) <= 0)
            return "no CUDA device: " + reason;
        cudaDeviceProp prop;
        check_cuda(cudaGetDeviceProperties(&prop, 0), "cudaGetDeviceProperties");
        int driver = 0, runtime = 0;
        cudaDriverGetVersion(&driver);
        cudaRuntimeGetVersion(&runtime);
        auto version = [](int v) { return std::to_string(v / 1000) + "." + std::to_string(v % 1000 / 10); };
        return std::string(prop.name) + " (sm_" + std::to_string(prop.major) + std::to_string(prop.minor) + ", "
            + std::to_string(prop.multiProcessorCount) + " SMs, " + std::to_string(prop.totalGlobalMem >> 20)
            + " MiB; driver CUDA " + version(driver) + ", runtime " + version(runtime) + ")";
    }

    void require_cuda_device(const std::string& what)
    {
        std::string reason;
        if (device_count(&reason) <= 0)
            throw std::runtime_error("no CUDA device: " + what + " needs a GPU (" + reason + ")");
    }

    void check_cuda(cudaError_t error, const char* what)
    {
        if (error != cudaSuccess)
            throw std::runtime_error(
                std::string(what) + " failed: " + cudaGetErrorName(error) + ": " + cudaGetErrorString(error));
    }

} // namespace gpu
} // namespace diffipc
