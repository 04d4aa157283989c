#pragma once
/// @file sparse_assembler.hpp
/// Assembly of symmetric dof-level matrices into a pattern computed once.
/// The pattern is the union of the element stencils (every dof of every vertex
/// of an element couples to every other) and the diagonal; only the lower
/// triangle is stored, which is what CHOLMOD reads. Elements are greedily
/// colored so that elements of one color share no vertex: scattering a color
/// in parallel has no write conflicts and the sum order is deterministic.

#include "forward/common/parallel.hpp"
#include "forward/common/types.hpp"

#include <cstdint>

#include <vector>

namespace diffipc {

class SparseAssembler {
public:
    /// @param dim          spatial dimension (dofs per vertex)
    /// @param num_vertices #V
    /// @param elements     #E by (dim+1) vertex indices (or any number of vertices per row)
    /// @param colored      false: no coloring (colors() stays empty), for patterns whose elements
    ///                     all share vertices (a periodic cell's macro pseudo-vertices) and are
    ///                     not assembled per element
    void build(int dim, Index num_vertices, const MatrixXi& elements, bool colored = true);

    void set_zero();
    /// @brief Adds the element matrix Ke (dim*(dim+1) square, local dofs
    /// vertex-major, column-major storage) of element e. Safe to call
    /// concurrently for elements of one color.
    void add_element(Index e, const double* Ke);
    /// @brief Adds v to the diagonal entry of `dof`.
    void add_diagonal(Index dof, double v);
    /// @brief Adds a local matrix K (n*dim square, column-major, local dofs
    /// vertex-major; n <= 4) coupling `vertices` whose pairs need not be in the element
    /// pattern (contact). Not thread-safe: see reserve_locals(); call finalize() after the last one.
    void add_local(const Index* vertices, int n, const double* K);
    /// @brief Reserves `count` local matrices after those added so far; returns the index
    /// of the first. Fill each with set_local(), concurrently for distinct indices.
    size_t reserve_locals(size_t count);
    /// @brief Sets reserved local matrix `i` (arguments as add_local). Thread-safe for distinct i.
    void set_local(size_t i, const Index* vertices, int n, const double* K);
    /// @brief Merges the local matrices into matrix(), in parallel: each column is summed
    /// by one task in the order the locals were added, so the values do not depend on the
    /// thread count. The extra pattern remembers vertex pairs seen before, so that a contact
    /// set that comes back does not change the pattern (and CHOLMOD's analysis) again.
    void finalize();
    /// @brief Adds a symmetric matrix given by its lower triangle (this assembler's size): a periodic
    /// cell's reduced Hessian (forward/periodic/periodic_potential.hpp), contact through periodic
    /// images. Entries outside the element pattern are added as local matrices of their vertex
    /// pair (add_local: not thread-safe; finalize() must follow).
    void add_matrix(const SparseMatrixd& lower);
    /// @brief Replaces the rows and columns of `constrained` dofs by identity rows.
    void apply_constraints(const std::vector<char>& constrained);

    const std::vector<std::vector<Index>>& colors() const { return m_colors; }
    /// The assembled matrix (lower triangle): the element pattern, plus the extra pattern once local matrices were
    /// added.
    SparseMatrixd& matrix() { return m_has_extra ? m_combined : m_matrix; }
    const SparseMatrixd& matrix() const { return m_has_extra ? m_combined : m_matrix; }
    Index size() const { return m_matrix.rows(); }

private:
    static constexpr int MAX_LOCAL_VERTICES = 4;
    bool in_element_pattern(Index column_vertex, Index row_vertex) const;
    void rebuild_combined_pattern();

    int m_dim = 0;
    int m_local = 0; // dim * (dim + 1)
    SparseMatrixd m_matrix;
    std::vector<int> m_element_slots; // #E * m_local^2, value index or -1 (upper triangle)
    std::vector<int> m_diagonal_slots;
    std::vector<std::vector<Index>> m_colors;

    // This assembly's local matrices: up to 4 vertices (-1 padded) and an (n dim)^2 block each.
    std::vector<Index> m_local_vertices;
    std::vector<int> m_local_count;
    std::vector<double> m_local_values; // stride (4 dim)^2
    VertexScatter m_local_scatter;

    // Remembered vertex pairs outside the element pattern, key (column vertex << 32) | row vertex, sorted.
    std::vector<uint64_t> m_extra_blocks;
    SparseMatrixd m_combined; // element pattern + extra blocks
    std::vector<int> m_element_to_combined; // value index in m_combined of each value of m_matrix
    bool m_combined_valid = false;
    bool m_has_extra = false;
};

} // namespace diffipc
