#pragma once
/// @file sparse_assembler.hpp
/// Assembly of symmetric dof-level matrices into a pattern computed once.
/// The pattern is the union of the element stencils (every dof of every vertex
/// of an element couples to every other) and the diagonal; only the lower
/// triangle is stored, which is what CHOLMOD reads. Elements are greedily
/// colored so that elements of one color share no vertex: scattering a color
/// in parallel has no write conflicts and the sum order is deterministic.

#include "forward/common/types.hpp"

#include <vector>

namespace diffipc {

class SparseAssembler {
public:
    /// @param dim          spatial dimension (dofs per vertex)
    /// @param num_vertices #V
    /// @param elements     #E by (dim+1) vertex indices
    void build(int dim, Index num_vertices, const MatrixXi& elements);

    void set_zero();
    /// @brief Adds the element matrix Ke (dim*(dim+1) square, local dofs
    /// vertex-major, column-major storage) of element e. Safe to call
    /// concurrently for elements of one color.
    void add_element(Index e, const double* Ke);
    /// @brief Adds v to the diagonal entry of `dof`.
    void add_diagonal(Index dof, double v);
    /// @brief Replaces the rows and columns of `constrained` dofs by identity rows.
    void apply_constraints(const std::vector<char>& constrained);

    const std::vector<std::vector<Index>>& colors() const { return m_colors; }
    SparseMatrixd& matrix() { return m_matrix; }
    const SparseMatrixd& matrix() const { return m_matrix; }
    Index size() const { return m_matrix.rows(); }

private:
    int m_dim = 0;
    int m_local = 0; // dim * (dim + 1)
    SparseMatrixd m_matrix;
    std::vector<int> m_element_slots; // #E * m_local^2, value index or -1 (upper triangle)
    std::vector<int> m_diagonal_slots;
    std::vector<std::vector<Index>> m_colors;
};

} // namespace diffipc
