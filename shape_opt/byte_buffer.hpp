#pragma once
/// @file byte_buffer.hpp
/// Values as bytes and back, for the messages between processes (distribution.cpp,
/// case_distribution.cpp): plain values copied byte for byte (processes of one machine type),
/// strings and arrays with their length first. Reading checks every length against the bytes left.

#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace diffipc {

struct ByteWriter {
    std::string bytes;
    template <class T> void put(const T& v)
    {
        static_assert(std::is_trivially_copyable<T>::value, "bytes of a trivially copyable value");
        bytes.append(reinterpret_cast<const char*>(&v), sizeof(T));
    }
    void put_doubles(const double* v, size_t n)
    {
        put(uint64_t(n));
        bytes.append(reinterpret_cast<const char*>(v), n * sizeof(double));
    }
    void put_string(const std::string& s)
    {
        put(uint64_t(s.size()));
        bytes += s;
    }
};

struct ByteReader {
    const std::string& bytes;
    const char* context; ///< the reading function's name, first in its errors
    size_t at = 0;
    void need(size_t n, const char* what)
    {
        if (n > bytes.size() - at)
            throw std::invalid_argument(std::string(context) + ": truncated at " + what + " (byte " + std::to_string(at)
                + " of " + std::to_string(bytes.size()) + ")");
    }
    template <class T> T get(const char* what)
    {
        need(sizeof(T), what);
        T v;
        std::memcpy(&v, bytes.data() + at, sizeof(T));
        at += sizeof(T);
        return v;
    }
    /// A count of entries of `element_bytes` each, checked against the bytes left.
    uint64_t count(const char* what, uint64_t element_bytes)
    {
        const uint64_t n = get<uint64_t>(what);
        if (element_bytes > 0 && n > (bytes.size() - at) / element_bytes)
            throw std::invalid_argument(std::string(context) + ": " + what + " claims " + std::to_string(n)
                + " entries, more than the bytes left");
        return n;
    }
    void doubles(double* to, uint64_t n, const char* what)
    {
        need(n * sizeof(double), what);
        std::memcpy(to, bytes.data() + at, n * sizeof(double));
        at += n * sizeof(double);
    }
    std::string string(const char* what)
    {
        const uint64_t length = count(what, 1);
        std::string s = bytes.substr(at, length);
        at += length;
        return s;
    }
    void finish()
    {
        if (at != bytes.size())
            throw std::invalid_argument(
                std::string(context) + ": " + std::to_string(bytes.size() - at) + " bytes left over");
    }
};

} // namespace diffipc
