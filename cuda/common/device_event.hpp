#pragma once
/// @file device_event.hpp
/// A CUDA event owned by a C++ object (created with it, destroyed with it), for the timings the
/// GPU code reports. Host code; compiles with nvcc and with a plain C++ compiler.

#include "cuda/common/device.hpp"

namespace diffipc::gpu {

class DeviceEvent {
public:
    DeviceEvent() { check_cuda(cudaEventCreate(&m_event), "cudaEventCreate"); }
    ~DeviceEvent() { cudaEventDestroy(m_event); }
    DeviceEvent(const DeviceEvent&) = delete;
    DeviceEvent& operator=(const DeviceEvent&) = delete;

    /// @brief Records the event in the default stream.
    void record() { check_cuda(cudaEventRecord(m_event), "cudaEventRecord"); }
    /// @brief Waits for the event; `what` names the work before it in an error.
    void synchronize(const char* what) { check_cuda(cudaEventSynchronize(m_event), what); }
    /// @brief Milliseconds from `from` to this event (both recorded and complete).
    float ms_since(const DeviceEvent& from) const
    {
        float ms = 0;
        check_cuda(cudaEventElapsedTime(&ms, from.m_event, m_event), "cudaEventElapsedTime");
        return ms;
    }

private:
    cudaEvent_t m_event = nullptr;
};

} // namespace diffipc::gpu
