#pragma once
/// @file barrier_pairs.hpp
/// A list of contact pairs prepared for the barrier's evaluation on the host or the device
/// (host_barrier.hpp, device_barrier.hpp): checked, with each edge-edge pair's mollifier
/// threshold, and the incidence lists that gather per-pair gradients and Hessian blocks in a
/// fixed order. Built on the host (plain C++) whenever the pair list changes.
///
/// Pair layout (BarrierPair): `kind` is int(ContactKind) = int(diffipc::ContactKind); `vertices`
/// holds contact_num_vertices(kind) full-mesh vertex indices in ContactKind's order (vertex-edge:
/// v, e0, e1; vertex-face: v, t0, t1, t2; edge-edge: ea0, ea1, eb0, eb1; vertex-plane: v, the
/// plane's point), the remaining entries -1; `plane` is a vertex-plane pair's index into the
/// plane normals. A diffipc::Contact maps to it field by field (its distance_type is not needed:
/// the type is classified at the positions the barrier is evaluated at, as on the CPU).
///
/// Contact Hessian pattern (the "second BSR matrix"): the contact blocks do not fit the elastic
/// mesh's fixed pattern, so they go into a BSR matrix of their own (cuda/linalg/bsr_matrix.hpp
/// layout, #V block rows, dim by dim blocks) whose blocks are the sorted unique vertex pairs
/// (v_a, v_b) of every pair, a and b over its vertices (diagonal blocks included, both
/// triangles). Rows of vertices in no pair are empty. The Newton system's matrix is then the sum
/// of the elastic and the contact matrices (sum_operator.hpp).
///
/// Incidence codes: a pair p's vertex a is p * 4 + a (the CPU VertexScatter's k * slots + a with
/// 4 slots); its local block (a, b) is p * 16 + a * 4 + b. Each vertex and each block slot lists
/// its codes in increasing order, i.e. in pair order, as the CPU sums them.

#include <cstddef>
#include <vector>

namespace diffipc::gpu {

/// One contact pair (layout in the file comment).
struct BarrierPair {
    int kind = 1;
    int vertices[4] = { -1, -1, -1, -1 };
    int plane = -1;
};

/// The barrier's parameters (ContactSettings' kappa, dhat, min_distance).
struct BarrierSettings {
    double kappa = 1; ///< barrier stiffness (the penalty's stiffness, N/m, with `penalty`)
    double dhat = 1e-3; ///< activation distance (m)
    double dmin = 0; ///< minimum separation (m)
    /// The penalty baseline instead of the barrier (pair_barrier.cuh, PairModel).
    bool penalty = false;
};

struct BarrierPairs {
    int dim = 0;
    int num_vertices = 0;
    int num_pairs = 0;
    /// Per pair, structure of arrays: kind[p]; vertices[a * #P + p] (-1 where unused); plane[p]
    /// (-1 unless vertex-plane); eps_x[p], the mollifier threshold at rest (0 unless edge-edge).
    std::vector<int> kind, vertices, plane;
    std::vector<double> eps_x;

    /// The contact BSR pattern: #V + 1 row offsets, block columns increasing within a row.
    std::vector<int> row_offsets, col_indices;
    /// Block rows (= vertices) with at least one block, increasing.
    std::vector<int> rows;
    /// #slots + 1 offsets into slot_codes; codes p * 16 + a * 4 + b, increasing per slot.
    std::vector<int> slot_offsets, slot_codes;
    /// #V + 1 offsets into vertex_codes; codes p * 4 + a, increasing per vertex.
    std::vector<int> vertex_offsets, vertex_codes;

    int num_slots() const { return int(col_indices.size()); }
};

/// @brief Checks pair p of a list (prepare_barrier_pairs' checks, below), for callers that prepare the pairs
/// otherwise (on the GPU). @throws std::invalid_argument naming the pair
void check_barrier_pair(int dim, int num_vertices, int num_planes, const BarrierPair& pair, size_t p);

/// @brief Checks a pair list and prepares it (layouts in the file comment).
/// @param dim             2 or 3
/// @param rest_positions  #V * dim rest positions (m), flattened vertex-major; the edge-edge
///                        mollifier thresholds are computed from them, as the CPU does
/// @param num_planes      the number of plane normals a vertex-plane pair may index
/// @param pairs           the pairs, in the order their contributions are summed
/// @throws std::invalid_argument naming the pair for an unknown kind, a kind the dimension does
///         not have (vertex-face and edge-edge need 3D), a vertex index out of range or a
///         repeated vertex, a plane index out of range, or more pairs than the int codes hold
BarrierPairs prepare_barrier_pairs(
    int dim, const std::vector<double>& rest_positions, int num_planes, const std::vector<BarrierPair>& pairs);

} // namespace diffipc::gpu
