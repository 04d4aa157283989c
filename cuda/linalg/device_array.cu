#include "cuda/linalg/device_array.hpp"

#include "cuda/common/device.hpp"

#include <cuda_runtime.h>

namespace diffipc::gpu::detail {

void* device_allocate(size_t bytes)
{
    void* pointer = nullptr;
    check_cuda(cudaMalloc(&pointer, bytes), "cudaMalloc");
    return pointer;
}

void device_free(void* pointer) noexcept
{
    if (pointer)
        cudaFree(pointer);
}

void copy_host_to_device(void* device, const void* host, size_t bytes)
{
    check_cuda(cudaMemcpy(device, host, bytes, cudaMemcpyHostToDevice), "cudaMemcpy to the device");
}

void copy_device_to_host(void* host, const void* device, size_t bytes)
{
    check_cuda(cudaMemcpy(host, device, bytes, cudaMemcpyDeviceToHost), "cudaMemcpy to the host");
}

void copy_device_to_device(void* to, const void* from, size_t bytes)
{
    check_cuda(cudaMemcpy(to, from, bytes, cudaMemcpyDeviceToDevice), "cudaMemcpy on the device");
}

void device_set_zero(void* device, size_t bytes) { check_cuda(cudaMemset(device, 0, bytes), "cudaMemset"); }

} // namespace diffipc::gpu::detail
