#pragma once
/// @file device_friction.hpp
/// Lagged smoothed Coulomb friction on the GPU: the device twin of FrictionPotential
/// (forward/contact/friction/friction_potential.hpp) for the lagged data of one Newton solve,
/// D(x) = sum_k mu_k lambda_k f0(|u_k|), u_k = T_k^T sum_i gamma_ki (x_i - x0_i), with each pair's
/// value, gradient and Hessian from forward/kernels/friction_pair.hpp (the formulas the CPU runs). The Hessian is
/// PSD by construction (FrictionPotential's file comment), so `project` changes nothing.
///
/// The pairs are set on the host once per lagging (the CPU's FrictionPotential::lag gives them), checked
/// there; their contact pattern and incidence lists are prepared on the GPU by a DeviceBarrier that holds
/// the same pairs (DeviceBarrier::set_pairs_device: stable radix sorts, the host preparation's arrays),
/// and the gathers are the barrier's (pair_gather.hpp): per vertex and per block slot in pair order, no
/// atomics, the same bits on every call.
///
/// Layouts: x, x0 and gradients #V * dim doubles, flattened vertex-major (xyzxyz), m and N; the
/// Hessian a DeviceBsrMatrix on the friction pairs' contact pattern (barrier_pairs.hpp), to be added
/// to the Newton matrix by a SumOperator. Host API in plain C++.
///
/// Not covered: periodic images.

#include "cuda/common/device_potential.hpp"
#include "cuda/common/kernels.cuh"
#include "cuda/contact/barrier_pairs.hpp"
#include "cuda/contact/device_barrier.hpp"
#include "cuda/linalg/bsr_matrix.hpp"
#include "cuda/linalg/device_array.hpp"
#include "forward/kernels/friction_pair.hpp"

#include <vector>

namespace diffipc::gpu {

class DeviceFriction : public DevicePotential {
public:
    /// @brief The mesh's size and rest positions (#V * dim; prepare_barrier_pairs checks the pairs
    /// against them) and the number of planes a vertex-plane pair may index. Clears the pairs.
    /// @throws std::invalid_argument for dim not 2 or 3 or a size that does not divide
    void upload(int dim, const std::vector<double>& rest_positions, int num_planes);

    /// @brief Sets the lagged pairs: their vertices (kind, vertices, plane as BarrierPair) and their
    /// frozen data (weights gamma, tangents T, mu lambda), in the order their terms are summed.
    /// @throws std::invalid_argument naming the pair for a bad pair (prepare_barrier_pairs), a size
    ///         mismatch, a num_vertices that is not the kind's, or non-finite data
    void set_pairs(const std::vector<BarrierPair>& pairs, const std::vector<FrictionPair>& data);
    /// @brief The start-of-step positions x0 (#V * dim, m) and eps = eps_v h (> 0, m).
    /// @throws std::invalid_argument on a size mismatch or an eps that is not positive and finite
    void set_step_start(const std::vector<double>& x_start, double eps);

    int num_pairs() const { return m_layout.num_pairs(); }
    int dim() const { return m_dim; }
    int num_dofs() const override { return m_num_vertices * m_dim; }
    double eps() const { return m_eps; }

    /// @name Device-resident evaluation: d_x and d_g are num_dofs() doubles in GPU memory.
    /// @{
    /// @brief D(x). Copies one double back.
    double energy_device(const double* d_x) const override;
    /// @brief d_g += weight * dD/dx. Asynchronous.
    void add_gradient_device(const double* d_x, double weight, double* d_g) const override;
    /// @brief H += weight * d2D/dx2 (PSD; `project` ignored). Asynchronous.
    /// @param H a matrix from make_hessian_matrix() for the current pairs
    /// @throws std::invalid_argument if H does not have the current pairs' pattern
    void add_hessian_device(const double* d_x, double weight, bool project, DeviceBsrMatrix& H) const override;
    /// @}
    /// @brief A zero matrix on the current pairs' contact pattern.
    DeviceBsrMatrix make_hessian_matrix() const override;

    /// @brief hessian() = weight * d2D/dx2 at d_x (the Newton solve's friction matrix). Asynchronous.
    void assemble_hessian(const double* d_x, double weight);
    /// The matrix assemble_hessian() fills, on the current pairs' pattern (made by set_pairs()).
    const DeviceBsrMatrix& hessian() const { return m_hessian; }

private:
    const char* potential_name() const override { return "DeviceFriction"; }

    int m_dim = 0, m_num_vertices = 0, m_num_planes = 0;
    double m_eps = 0;
    DeviceBarrier m_layout; // the pairs' pattern and incidence lists (its barrier is never evaluated)
    DeviceArray<int> m_packed; // the pairs as set_pairs_device takes them
    DeviceArray<FrictionPair> m_data;
    DeviceArray<double> m_x_start;
    DeviceBsrMatrix m_hessian;
    mutable DeviceArray<double> m_pair_energy, m_pair_gradient, m_pair_hessian, m_partials, m_scalar;
};

} // namespace diffipc::gpu
