#include "forward/solver/sparse_assembler.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <iterator>
#include <stdexcept>

namespace diffipc {

void SparseAssembler::build(int dim, Index num_vertices, const MatrixXi& elements)
{
    m_dim = dim;
    const int nv = int(elements.cols());
    m_local = dim * nv;
    const Index n = num_vertices * dim;

    // Column-wise sets of rows (lower triangle) from the vertex adjacency.
    std::vector<std::vector<int>> vertex_neighbors(static_cast<size_t>(num_vertices));
    for (Index e = 0; e < elements.rows(); ++e)
        for (int a = 0; a < nv; ++a)
            for (int b = 0; b < nv; ++b)
                vertex_neighbors[size_t(elements(e, a))].push_back(elements(e, b));
    std::vector<int> outer(size_t(n) + 1, 0);
    std::vector<int> inner;
    for (Index v = 0; v < num_vertices; ++v) {
        auto& nb = vertex_neighbors[size_t(v)];
        nb.push_back(int(v));
        std::sort(nb.begin(), nb.end());
        nb.erase(std::unique(nb.begin(), nb.end()), nb.end());
        for (int c = 0; c < dim; ++c) {
            const Index col = v * dim + c;
            for (int w : nb)
                for (int r = 0; r < dim; ++r) {
                    const Index row = Index(w) * dim + r;
                    if (row >= col)
                        inner.push_back(int(row));
                }
            outer[size_t(col) + 1] = int(inner.size());
        }
    }
    std::vector<double> zeros(inner.size(), 0.0);
    m_matrix = Eigen::Map<const SparseMatrixd>(n, n, Index(inner.size()), outer.data(), inner.data(), zeros.data());
    m_matrix.makeCompressed();

    const int* ip = m_matrix.innerIndexPtr();
    const int* op = m_matrix.outerIndexPtr();
    auto slot = [&](Index row, Index col) {
        const int* begin = ip + op[col];
        const int* end = ip + op[col + 1];
        const int* it = std::lower_bound(begin, end, int(row));
        return int(it - ip);
    };
    m_element_slots.assign(size_t(elements.rows()) * size_t(m_local * m_local), -1);
    for (Index e = 0; e < elements.rows(); ++e)
        for (int a = 0; a < m_local; ++a)
            for (int b = 0; b < m_local; ++b) {
                const Index row = Index(elements(e, a / dim)) * dim + a % dim;
                const Index col = Index(elements(e, b / dim)) * dim + b % dim;
                if (row >= col)
                    m_element_slots[size_t(e) * size_t(m_local * m_local) + size_t(b * m_local + a)] = slot(row, col);
            }
    m_diagonal_slots.resize(size_t(n));
    for (Index i = 0; i < n; ++i)
        m_diagonal_slots[size_t(i)] = slot(i, i);

    // Greedy coloring: an element takes the smallest color none of its vertices has seen.
    constexpr int WORDS = 8; // up to 512 colors
    std::vector<std::array<uint64_t, WORDS>> used(static_cast<size_t>(num_vertices));
    for (auto& u : used)
        u.fill(0);
    m_colors.clear();
    for (Index e = 0; e < elements.rows(); ++e) {
        std::array<uint64_t, WORDS> forbidden {};
        for (int a = 0; a < nv; ++a)
            for (int w = 0; w < WORDS; ++w)
                forbidden[size_t(w)] |= used[size_t(elements(e, a))][size_t(w)];
        int color = -1;
        for (int w = 0; w < WORDS && color < 0; ++w)
            if (~forbidden[size_t(w)])
                color = w * 64 + __builtin_ctzll(~forbidden[size_t(w)]);
        if (color < 0)
            throw std::runtime_error("element coloring needs more than 512 colors");
        for (int a = 0; a < nv; ++a)
            used[size_t(elements(e, a))][size_t(color / 64)] |= uint64_t(1) << (color % 64);
        if (size_t(color) >= m_colors.size())
            m_colors.resize(size_t(color) + 1);
        m_colors[size_t(color)].push_back(e);
    }
}

void SparseAssembler::set_zero()
{
    std::fill_n(m_matrix.valuePtr(), m_matrix.nonZeros(), 0.0);
    m_local_entries.clear();
    m_has_extra = false;
}

void SparseAssembler::add_local(const Index* vertices, int n, const double* K)
{
    const int m = n * m_dim;
    for (int b = 0; b < m; ++b)
        for (int a = 0; a < m; ++a) {
            const int row = int(vertices[a / m_dim] * m_dim + a % m_dim);
            const int col = int(vertices[b / m_dim] * m_dim + b % m_dim);
            if (row >= col)
                m_local_entries.push_back({ col, row, K[size_t(b) * size_t(m) + size_t(a)] });
        }
}

void SparseAssembler::finalize()
{
    if (m_local_entries.empty() && m_extra_pattern.empty()) {
        m_has_extra = false;
        return;
    }
    std::vector<std::pair<int, int>> current;
    current.reserve(m_local_entries.size());
    for (const Entry& e : m_local_entries)
        current.emplace_back(e.col, e.row);
    std::sort(current.begin(), current.end());
    current.erase(std::unique(current.begin(), current.end()), current.end());
    std::vector<std::pair<int, int>> merged;
    merged.reserve(current.size() + m_extra_pattern.size());
    std::set_union(
        current.begin(), current.end(), m_extra_pattern.begin(), m_extra_pattern.end(), std::back_inserter(merged));
    // Forget old pairs once they dominate, so a long sliding contact does not
    // accumulate fill-in without bound.
    if (merged.size() > 4 * current.size() + 4096)
        merged = current;
    m_extra_pattern.swap(merged);

    std::vector<Eigen::Triplet<double, int>> triplets;
    triplets.reserve(m_extra_pattern.size() + m_local_entries.size());
    for (const auto& [col, row] : m_extra_pattern)
        triplets.emplace_back(row, col, 0.0);
    for (const Entry& e : m_local_entries)
        triplets.emplace_back(e.row, e.col, e.value);
    SparseMatrixd extra(m_matrix.rows(), m_matrix.cols());
    extra.setFromTriplets(triplets.begin(), triplets.end());
    m_combined = m_matrix + extra;
    m_combined.makeCompressed();
    m_has_extra = true;
}

void SparseAssembler::add_element(Index e, const double* Ke)
{
    double* values = m_matrix.valuePtr();
    const int* slots = m_element_slots.data() + size_t(e) * size_t(m_local * m_local);
    for (int k = 0; k < m_local * m_local; ++k)
        if (slots[k] >= 0)
            values[slots[k]] += Ke[k];
}

void SparseAssembler::add_diagonal(Index dof, double v) { m_matrix.valuePtr()[m_diagonal_slots[size_t(dof)]] += v; }

void SparseAssembler::apply_constraints(const std::vector<char>& constrained)
{
    SparseMatrixd& A = matrix();
    double* values = A.valuePtr();
    const int* ip = A.innerIndexPtr();
    const int* op = A.outerIndexPtr();
    for (Index col = 0; col < A.cols(); ++col)
        for (int k = op[col]; k < op[col + 1]; ++k) {
            const Index row = ip[k];
            if (constrained[size_t(row)] || constrained[size_t(col)])
                values[k] = row == col ? 1.0 : 0.0;
        }
}

} // namespace diffipc
