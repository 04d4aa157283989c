#pragma once
/// @file pair_gather.hpp
/// The deterministic gathers of per-pair contributions (barrier_pairs.hpp's incidence lists) into a
/// gradient and a contact-pattern Hessian, shared by the pair potentials on the device (the barrier,
/// device_barrier.hpp; lagged friction, device_friction.hpp). Each vertex and each block slot sums its
/// pairs' contributions in pair order, as the CPU's VertexScatter and SparseAssembler do: no atomics,
/// the same bits on every call. Host-callable launches (asynchronous).
///
/// Per-pair layouts (np pairs, L = 4 dim local dofs per pair, structure of arrays):
/// - local gradients: entry k = a dim + i of pair p at k np + p;
/// - local Hessians: entry (r, c) of pair p at (r L + c) np + p.

namespace diffipc::gpu {

/// @brief d_g[v dim + i] += scale * the local gradients of v's pairs, for the vertices in `rows`.
/// @param num_rows the vertices in some pair (BarrierPairs::rows), @param rows their indices (device)
/// @param offsets, codes BarrierPairs::vertex_offsets and vertex_codes (device)
void gather_pair_gradients(int num_rows, int dim, int np, const int* rows, const int* offsets, const int* codes,
    const double* local, double scale, double* d_g);

/// @brief d_values (a contact-pattern BSR matrix's values) += the local Hessian blocks of each slot's pairs.
/// @param slots the pattern's blocks, @param offsets, codes BarrierPairs::slot_offsets and slot_codes (device)
void gather_pair_hessians(
    int slots, int dim, int np, const int* offsets, const int* codes, const double* local, double* d_values);

} // namespace diffipc::gpu
