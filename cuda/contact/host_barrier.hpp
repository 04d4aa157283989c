#pragma once
/// @file host_barrier.hpp
/// The CPU twin of DeviceBarrier (device_barrier.hpp): the same per-pair functions
/// (pair_barrier.cuh) and the same fixed-order gathers, run on the host. It is what the CPU tests
/// (no GPU) compare with ContactPotential, and a reference for the device results. Plain C++.
///
/// Layouts as DeviceBarrier: positions and gradients #V * dim doubles, flattened vertex-major;
/// plane normals #planes * 3 (unit, z = 0 in 2D); the Hessian a HostBsrMatrix on the contact
/// pattern of the pair list (barrier_pairs.hpp).

#include "cuda/contact/barrier_pairs.hpp"
#include "cuda/linalg/bsr_matrix.hpp"

#include <vector>

namespace diffipc::kernels {
struct PairModel; // forward/kernels/contact_pair.hpp
} // namespace diffipc::kernels

namespace diffipc::gpu {

using kernels::PairModel;

class HostBarrier {
public:
    /// @brief The mesh's rest positions (#V * dim, for the mollifier thresholds) and the planes'
    /// unit normals (#planes * 3). Clears the pair list.
    void set_mesh(int dim, const std::vector<double>& rest_positions, const std::vector<double>& plane_normals);
    void set_settings(const BarrierSettings& settings) { m_settings = settings; }
    /// @brief Prepares the pair list (prepare_barrier_pairs; throws as it does).
    void set_pairs(const std::vector<BarrierPair>& pairs);
    const BarrierPairs& pairs() const { return m_pairs; }

    /// @brief B(x) = kappa sum_k m_k b_k, summed in pair order; +inf if a pair intersects (the
    /// barrier; the penalty, BarrierSettings::penalty, is finite everywhere).
    double energy(const std::vector<double>& x) const;
    /// @brief weight * kappa * dB/dx (#V * dim): per-pair gradients gathered per vertex in pair order.
    std::vector<double> gradient(const std::vector<double>& x, double weight = 1.0) const;
    /// @brief weight * kappa * the sum of the pair Hessians, each projected to PSD first if
    /// `project`, on the contact pattern (each block summed in pair order).
    HostBsrMatrix hessian(const std::vector<double>& x, bool project, double weight = 1.0) const;

private:
    void check_x(size_t n) const;
    /// The pair model of the settings (pair_barrier.cuh).
    PairModel model() const;

    int m_dim = 0;
    std::vector<double> m_rest, m_normals;
    BarrierSettings m_settings;
    BarrierPairs m_pairs;
};

} // namespace diffipc::gpu
