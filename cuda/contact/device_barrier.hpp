#pragma once
/// @file device_barrier.hpp
/// The IPC barrier potential B(x) = kappa sum_k m_k b(s_k - dmin^2, shat) of a list of contact
/// pairs, evaluated on the GPU: the device twin of ContactPotential's barrier
/// (forward/contact/contact_potential.hpp) for a given pair list, with the same per-pair
/// formulas (pair_barrier.cuh: distance types classified at x, edge-edge mollifier, vertex-plane
/// pairs, minimum separation) and the same per-pair PSD projection. Host API in plain C++.
///
/// Layouts (barrier_pairs.hpp for the pairs and the contact Hessian's pattern):
/// - positions x and gradients: #V * dim doubles in GPU memory (the *_device functions) or on the
///   host, flattened vertex-major (xyzxyz), m and N;
/// - plane normals: #planes * 3 unit normals (z = 0 in 2D), indexed by the vertex-plane pairs;
/// - Hessian: a DeviceBsrMatrix on the contact pattern of the current pair list
///   (make_hessian_matrix(), #V block rows of dim by dim blocks; only the rows of vertices in a
///   pair have blocks). Add it to the elastic matrix with a SumOperator (sum_operator.hpp).
///
/// Determinism: per-pair energies are summed by cuda/linalg/reduction.hpp's fixed tree; per-pair
/// gradients are gathered per vertex and per-pair Hessian blocks per block slot over incidence
/// lists in pair order (as the CPU's VertexScatter and SparseAssembler sum them). No atomics:
/// repeated evaluations give the same bits.
///
/// Not covered (yet): the penalty model (ContactSettings::penalty), periodic images, the shape
/// derivative, building the pair list (the broad phase's job; the CPU's ContactPotential::contacts
/// gives one), CCD.

#include "cuda/common/device_potential.hpp"
#include "cuda/contact/barrier_pairs.hpp"
#include "cuda/linalg/bsr_matrix.hpp"
#include "cuda/linalg/device_array.hpp"

#include <vector>

namespace diffipc::gpu {

class DeviceBarrier : public DevicePotential {
public:
    /// @brief The mesh's rest positions (#V * dim, for the edge-edge mollifier thresholds) and the
    /// planes' unit normals (#planes * 3); copies the normals to the GPU. Clears the pair list.
    /// @throws std::invalid_argument for dim not 2 or 3 or sizes that do not divide
    void upload(int dim, const std::vector<double>& rest_positions, const std::vector<double>& plane_normals);
    void set_settings(const BarrierSettings& settings) { m_settings = settings; }
    const BarrierSettings& settings() const { return m_settings; }

    /// @brief Sets the active pairs: prepares them on the host (prepare_barrier_pairs, which throws
    /// on a bad pair) and copies them and their incidence lists to the GPU. Call whenever the
    /// pair list changes; then make a new Hessian matrix (the pattern changed).
    void set_pairs(const std::vector<BarrierPair>& pairs);
    /// @brief set_pairs() from a pair list in GPU memory, prepared on the GPU (device_barrier_pairs.cu):
    /// the same arrays, pattern and incidence lists as prepare_barrier_pairs, built by stable radix
    /// sorts (deterministic); only the contact pattern comes back to the host. Not checked: for pairs a
    /// checked source built (DeviceContact's classification of a checked collision mesh).
    /// @param d_pairs 6 ints per pair: kind, the 4 vertices (-1 unused), the plane (-1 unless vertex-plane)
    void set_pairs_device(const int* d_pairs, int num_pairs);
    /// The prepared pair list and the contact pattern (host copy; after set_pairs_device() only dim,
    /// num_vertices, num_pairs and the pattern's row_offsets and col_indices are filled).
    const BarrierPairs& pairs() const { return m_pairs; }
    int num_pairs() const { return m_pairs.num_pairs; }

    /// The prepared pair list's device arrays (barrier_pairs.hpp's layout), for another potential on the
    /// same pairs (DeviceFriction evaluates its own per-pair terms and gathers them with these lists).
    struct Layout {
        int num_pairs = 0, num_rows = 0, num_slots = 0;
        const int *vertices = nullptr, *rows = nullptr, *vertex_offsets = nullptr, *vertex_codes = nullptr,
                  *slot_offsets = nullptr, *slot_codes = nullptr;
    };
    Layout layout() const;
    int dim() const { return m_dim; }
    int num_dofs() const override { return m_num_vertices * m_dim; }

    /// @name Device-resident evaluation: d_x and d_g are num_dofs() doubles in GPU memory.
    /// @{
    /// @brief B(x) = kappa sum_k m_k b_k; +inf if a pair intersects (s - dmin^2 <= 0). Copies one
    /// double back.
    double energy_device(const double* d_x) const override;
    /// @brief d_g += weight * kappa * dB/dx (NaN on the vertices of an intersecting pair).
    /// Asynchronous.
    void add_gradient_device(const double* d_x, double weight, double* d_g) const override;
    /// @brief H += weight * kappa * sum_k H_k, each pair Hessian H_k projected to PSD first if
    /// `project` (the CPU's per-pair projection). Asynchronous.
    /// @param H a matrix from make_hessian_matrix() for the current pair list
    /// @throws std::invalid_argument if H does not have the current contact pattern
    void add_hessian_device(const double* d_x, double weight, bool project, DeviceBsrMatrix& H) const override;
    /// @}

    /// @brief A zero matrix on the current pair list's contact pattern.
    DeviceBsrMatrix make_hessian_matrix() const override;

    // Host conveniences energy(x), gradient(x), hessian_bsr(x): DevicePotential.

private:
    const char* potential_name() const override { return "DeviceBarrier"; }

    int m_dim = 0, m_num_vertices = 0;
    std::vector<double> m_rest;
    DeviceArray<double> m_d_rest; // the rest positions on the device (set_pairs_device's thresholds)
    int m_num_planes = 0;
    int m_num_rows = 0; // vertices in some pair (the gradient gather's rows)
    BarrierSettings m_settings;
    BarrierPairs m_pairs;
    DeviceArray<double> m_normals; // #planes * 3
    // The pair list (structure of arrays, barrier_pairs.hpp) and its incidence lists.
    DeviceArray<int> m_kind, m_vertices, m_plane;
    DeviceArray<double> m_eps_x;
    DeviceArray<int> m_rows, m_vertex_offsets, m_vertex_codes, m_slot_offsets, m_slot_codes;
    // Scratch: per-pair energies, gradients (4 dim * #P) and Hessians ((4 dim)^2 * #P), reductions.
    mutable DeviceArray<double> m_pair_energy, m_pair_gradient, m_pair_hessian, m_partials, m_scalar;
    // set_pairs_device's scratch: sort keys and values, flags, cub's temporary storage.
    DeviceArray<int> m_keys, m_sorted_keys, m_codes, m_heads, m_count, m_bounds, m_columns, m_block_rows;
    DeviceArray<long long> m_block_keys, m_sorted_block_keys, m_head_keys;
    DeviceArray<unsigned char> m_flags, m_temp;
};

} // namespace diffipc::gpu
