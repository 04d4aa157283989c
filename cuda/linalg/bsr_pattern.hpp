#pragma once
/// @file bsr_pattern.hpp
/// The fixed block-sparse pattern of a matrix assembled from elements (every vertex of an
/// element couples to every other, plus every diagonal block), and the incidence lists
/// that let the GPU gather per-element contributions into it deterministically: each
/// vertex, and each block slot, lists its contributions in increasing element order, so a
/// sum over them has the order of a serial element loop, whatever the scheduling. Computed
/// once on the host (plain C++).
///
/// Layouts: `elements` is #E by n vertex indices flattened element-major
/// (elements[e * n + a], n vertices per element). BSR: block row v holds the blocks
/// (v, col_indices[k]) for k in [row_offsets[v], row_offsets[v + 1]), columns increasing;
/// a block's index k is its "slot".

#include <vector>

namespace diffipc::gpu {

struct ElementBsrPattern {
    int num_vertices = 0;
    int vertices_per_element = 0; ///< n
    /// #V + 1 offsets into col_indices.
    std::vector<int> row_offsets;
    /// Block column of each slot (#slots), increasing within a block row.
    std::vector<int> col_indices;
    /// #E * n * n: the slot of block (elements[e n + a], elements[e n + b]) at e n^2 + a n + b.
    std::vector<int> element_slots;
    /// #slots + 1 offsets into slot_codes.
    std::vector<int> slot_offsets;
    /// Contributions to each slot as codes e n^2 + a n + b, increasing (element order).
    std::vector<int> slot_codes;
    /// #V + 1 offsets into vertex_codes.
    std::vector<int> vertex_offsets;
    /// Incidences of each vertex as codes e n + a, increasing (element order).
    std::vector<int> vertex_codes;

    int num_slots() const { return int(col_indices.size()); }
};

/// @brief Builds the pattern and incidence lists of #E elements with n vertices each.
/// @param num_vertices #V
/// @param vertices_per_element n (3 for triangles, 4 for tetrahedra)
/// @param elements #E * n vertex indices in [0, #V), element-major
/// @throws std::invalid_argument for an index out of range, a size that is not a multiple
///         of n, or more codes than an int holds
ElementBsrPattern element_bsr_pattern(int num_vertices, int vertices_per_element, const std::vector<int>& elements);

} // namespace diffipc::gpu
