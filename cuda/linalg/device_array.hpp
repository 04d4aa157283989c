#pragma once
/// @file device_array.hpp
/// An owning array in GPU memory (plain cudaMalloc, no managed memory), move-only. Host code;
/// this header compiles with a plain C++ compiler (it does not include the CUDA headers), so
/// that host APIs can hold device data without exposing CUDA types. CUDA errors throw
/// std::runtime_error naming the operation (cuda/common/device.hpp's check_cuda).

#include <cstddef>
#include <vector>

namespace diffipc::gpu {

namespace detail {
    void* device_allocate(size_t bytes);
    void device_free(void* pointer) noexcept;
    void copy_host_to_device(void* device, const void* host, size_t bytes);
    void copy_device_to_host(void* host, const void* device, size_t bytes);
    void copy_device_to_device(void* to, const void* from, size_t bytes);
    void device_set_zero(void* device, size_t bytes);
} // namespace detail

template <typename T> class DeviceArray {
public:
    DeviceArray() = default;
    explicit DeviceArray(size_t n) { resize(n); }
    explicit DeviceArray(const std::vector<T>& host) { upload(host); }
    ~DeviceArray() { detail::device_free(m_data); }
    DeviceArray(const DeviceArray&) = delete;
    DeviceArray& operator=(const DeviceArray&) = delete;
    DeviceArray(DeviceArray&& other) noexcept
        : m_data(other.m_data)
        , m_size(other.m_size)
    {
        other.m_data = nullptr;
        other.m_size = 0;
    }
    DeviceArray& operator=(DeviceArray&& other) noexcept
    {
        if (this != &other) {
            detail::device_free(m_data);
            m_data = other.m_data;
            m_size = other.m_size;
            other.m_data = nullptr;
            other.m_size = 0;
        }
        return *this;
    }

    /// @brief n elements, contents undefined (kept if n is the current size).
    void resize(size_t n)
    {
        if (n == m_size)
            return;
        detail::device_free(m_data);
        m_data = nullptr;
        m_size = 0;
        if (n > 0)
            m_data = static_cast<T*>(detail::device_allocate(n * sizeof(T)));
        m_size = n;
    }
    /// @brief Resizes to host.size() and copies host into the array.
    void upload(const std::vector<T>& host) { upload(host.data(), host.size()); }
    void upload(const T* host, size_t n)
    {
        resize(n);
        if (n > 0)
            detail::copy_host_to_device(m_data, host, n * sizeof(T));
    }
    /// @brief Copies the array to the host (blocks until the GPU is done with it).
    std::vector<T> download() const
    {
        std::vector<T> host(m_size);
        if (m_size > 0)
            detail::copy_device_to_host(host.data(), m_data, m_size * sizeof(T));
        return host;
    }
    void set_zero()
    {
        if (m_size > 0)
            detail::device_set_zero(m_data, m_size * sizeof(T));
    }

    T* data() { return m_data; }
    const T* data() const { return m_data; }
    size_t size() const { return m_size; }

private:
    T* m_data = nullptr;
    size_t m_size = 0;
};

} // namespace diffipc::gpu
