#pragma once
/// @file device_periodic_map.hpp
/// A periodic cell's map x = X + P q on the device (periodic_reduction.cuh has the formulas; the CPU's is
/// forward/periodic/periodic_map.hpp): P q, X + P q, and P^T g, for a reduced Newton step of a periodic
/// cell on the GPU (the cell's unknowns, the classes' fluctuations and its macro gradient G). P^T g is
/// deterministic: each class sums its vertices in increasing order, each of the dim^2 macro entries is a
/// reduction.hpp sum (a fixed tree), so two calls give the same bits.
///
/// DeviceNewton's periodic mode (set_periodic) uses it.
/// Host code; this header compiles with a plain C++ compiler (no CUDA headers).

#include "cuda/linalg/device_array.hpp"
#include "cuda/periodic/periodic_reduction.cuh"

#include <vector>

namespace diffipc::gpu {

class DevicePeriodicMap {
public:
    /// @param vertex_class #V classes in 0 .. C - 1, each class with at least one vertex
    ///        (PeriodicPairing::vertex_class)
    /// @param rest #V dim rest positions X, vertex-major; @param origin X_o (dim values); @param length L > 0
    /// @throws std::invalid_argument naming the input that does not fit
    DevicePeriodicMap(int dim, const std::vector<int>& vertex_class, const std::vector<double>& rest,
        const std::vector<double>& origin, double length);

    int dim() const { return m_view.dim; }
    int num_vertices() const { return m_view.num_vertices; }
    int num_classes() const { return m_view.num_classes; }
    /// C dim + dim^2
    int num_reduced() const { return gpu::num_reduced(m_view); }
    /// The map's device pointers, for kernels.
    const PeriodicView& view() const { return m_view; }

    /// d_x (#V dim) = P d_q, or X + P d_q with `with_rest` (asynchronous).
    void expand(const double* d_q, double* d_x, bool with_rest) const;
    /// d_gq (num_reduced()) = P^T d_g (#V dim); asynchronous, deterministic.
    void reduce(const double* d_g, double* d_gq);

private:
    PeriodicView m_view;
    DeviceArray<int> m_class, m_start, m_members;
    DeviceArray<double> m_lever, m_rest, m_terms, m_partials;
};

} // namespace diffipc::gpu
