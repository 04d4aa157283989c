#include "forward/solver/sparse_assembler.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <iterator>
#include <map>
#include <stdexcept>

#include <tbb/parallel_sort.h>

namespace diffipc {

void SparseAssembler::build(int dim, Index num_vertices, const MatrixXi& elements, bool colored)
{
    m_dim = dim;
    m_extra_blocks.clear();
    m_combined_valid = false;
    m_has_extra = false;
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

    m_colors.clear();
    if (!colored)
        return;
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
    m_local_vertices.clear();
    m_local_count.clear();
    m_local_values.clear();
    m_has_extra = false;
}

size_t SparseAssembler::reserve_locals(size_t count)
{
    const size_t first = m_local_count.size();
    const size_t stride = size_t(MAX_LOCAL_VERTICES * m_dim) * size_t(MAX_LOCAL_VERTICES * m_dim);
    m_local_vertices.resize((first + count) * MAX_LOCAL_VERTICES, -1);
    m_local_count.resize(first + count, 0);
    m_local_values.resize((first + count) * stride);
    return first;
}

void SparseAssembler::set_local(size_t i, const Index* vertices, int n, const double* K)
{
    if (n < 1 || n > MAX_LOCAL_VERTICES)
        throw std::logic_error("SparseAssembler::set_local: 1 to 4 vertices per local matrix");
    const size_t stride = size_t(MAX_LOCAL_VERTICES * m_dim) * size_t(MAX_LOCAL_VERTICES * m_dim);
    for (int a = 0; a < MAX_LOCAL_VERTICES; ++a)
        m_local_vertices[i * MAX_LOCAL_VERTICES + size_t(a)] = a < n ? vertices[a] : -1;
    m_local_count[i] = n;
    std::copy_n(K, size_t(n * m_dim) * size_t(n * m_dim), m_local_values.data() + i * stride);
}

void SparseAssembler::add_local(const Index* vertices, int n, const double* K)
{
    set_local(reserve_locals(1), vertices, n, K);
}

bool SparseAssembler::in_element_pattern(Index column_vertex, Index row_vertex) const
{
    const int* ip = m_matrix.innerIndexPtr();
    const int* op = m_matrix.outerIndexPtr();
    const Index col = column_vertex * m_dim, row = row_vertex * m_dim;
    return std::binary_search(ip + op[col], ip + op[col + 1], int(row));
}

void SparseAssembler::rebuild_combined_pattern()
{
    const Index n = m_matrix.rows();
    const Index nv = n / m_dim;
    // Extra row vertices of each column vertex (keys sorted by column vertex, then row vertex).
    std::vector<int64_t> extra_begin(size_t(nv) + 1, 0);
    for (uint64_t key : m_extra_blocks)
        ++extra_begin[size_t(key >> 32) + 1];
    for (Index v = 0; v < nv; ++v)
        extra_begin[size_t(v) + 1] += extra_begin[size_t(v)];
    const int* eo = m_matrix.outerIndexPtr();
    const int* ei = m_matrix.innerIndexPtr();
    std::vector<int> outer(size_t(n) + 1, 0);
    for (Index col = 0; col < n; ++col) {
        const Index v = col / m_dim;
        outer[size_t(col) + 1] = outer[size_t(col)] + (eo[col + 1] - eo[col])
            + int(m_dim * (extra_begin[size_t(v) + 1] - extra_begin[size_t(v)]));
    }
    std::vector<int> inner(size_t(outer.back()));
    m_element_to_combined.resize(size_t(m_matrix.nonZeros()));
    // Merge each column's element rows with its extra blocks' rows (disjoint, both sorted).
    tbb::parallel_for(tbb::blocked_range<Index>(0, n, 512), [&](const tbb::blocked_range<Index>& r) {
        for (Index col = r.begin(); col < r.end(); ++col) {
            const Index v = col / m_dim;
            int out = outer[size_t(col)];
            int k = eo[col];
            for (int64_t x = extra_begin[size_t(v)]; x < extra_begin[size_t(v) + 1]; ++x) {
                const int row0 = int((m_extra_blocks[size_t(x)] & 0xffffffffu) * uint64_t(m_dim));
                for (; k < eo[col + 1] && ei[k] < row0; ++k) {
                    m_element_to_combined[size_t(k)] = out;
                    inner[size_t(out++)] = ei[k];
                }
                for (int rr = 0; rr < m_dim; ++rr)
                    inner[size_t(out++)] = row0 + rr;
            }
            for (; k < eo[col + 1]; ++k) {
                m_element_to_combined[size_t(k)] = out;
                inner[size_t(out++)] = ei[k];
            }
        }
    });
    std::vector<double> zeros(inner.size(), 0.0);
    m_combined = Eigen::Map<const SparseMatrixd>(n, n, Index(inner.size()), outer.data(), inner.data(), zeros.data());
    m_combined.makeCompressed();
    m_combined_valid = true;
}

void SparseAssembler::finalize()
{
    const size_t count = m_local_count.size();
    if (count == 0 && m_extra_blocks.empty()) {
        m_has_extra = false;
        return;
    }
    // Vertex pairs of this assembly outside the element pattern (lower: column vertex < row vertex).
    std::vector<uint64_t> needed = parallel_collect<uint64_t>(count, 256, [&](size_t k, std::vector<uint64_t>& out) {
        const Index* v = &m_local_vertices[k * MAX_LOCAL_VERTICES];
        for (int a = 0; a < m_local_count[k]; ++a)
            for (int b = 0; b < m_local_count[k]; ++b)
                if (v[a] < v[b] && !in_element_pattern(v[a], v[b]))
                    out.push_back((uint64_t(v[a]) << 32) | uint64_t(v[b]));
    });
    tbb::parallel_sort(needed.begin(), needed.end());
    needed.erase(std::unique(needed.begin(), needed.end()), needed.end());
    if (!std::includes(m_extra_blocks.begin(), m_extra_blocks.end(), needed.begin(), needed.end())) {
        std::vector<uint64_t> merged;
        merged.reserve(needed.size() + m_extra_blocks.size());
        std::set_union(
            needed.begin(), needed.end(), m_extra_blocks.begin(), m_extra_blocks.end(), std::back_inserter(merged));
        // Forget old pairs once they dominate, so a long sliding contact does not
        // accumulate fill-in without bound.
        if (merged.size() > 4 * needed.size() + 512)
            merged = needed;
        m_extra_blocks.swap(merged);
        m_combined_valid = false;
    }
    if (!m_combined_valid)
        rebuild_combined_pattern();

    double* cv = m_combined.valuePtr();
    const double* ev = m_matrix.valuePtr();
    const Index nnz = m_combined.nonZeros(), enz = m_matrix.nonZeros();
    tbb::parallel_for(tbb::blocked_range<Index>(0, nnz, 1 << 14),
        [&](const tbb::blocked_range<Index>& r) { std::fill(cv + r.begin(), cv + r.end(), 0.0); });
    tbb::parallel_for(tbb::blocked_range<Index>(0, enz, 1 << 14), [&](const tbb::blocked_range<Index>& r) {
        for (Index k = r.begin(); k < r.end(); ++k)
            cv[m_element_to_combined[size_t(k)]] = ev[k];
    });

    // Each column vertex sums its locals in the order they were added.
    m_local_scatter.build(m_matrix.rows() / m_dim, count, MAX_LOCAL_VERTICES,
        [&](size_t k, int a) { return m_local_vertices[k * MAX_LOCAL_VERTICES + size_t(a)]; });
    const std::vector<Index>& touched = m_local_scatter.touched();
    const int* ip = m_combined.innerIndexPtr();
    const int* op = m_combined.outerIndexPtr();
    const size_t stride = size_t(MAX_LOCAL_VERTICES * m_dim) * size_t(MAX_LOCAL_VERTICES * m_dim);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, touched.size(), 64), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t t = r.begin(); t < r.end(); ++t) {
            const Index v = touched[t];
            for (const int64_t* code = m_local_scatter.begin(v); code != m_local_scatter.end(v); ++code) {
                const size_t k = size_t(*code / MAX_LOCAL_VERTICES);
                const int a = int(*code % MAX_LOCAL_VERTICES);
                const int nk = m_local_count[k];
                const int m = nk * m_dim;
                const Index* verts = &m_local_vertices[k * MAX_LOCAL_VERTICES];
                const double* K = m_local_values.data() + k * stride;
                for (int c = 0; c < m_dim; ++c) {
                    const Index col = v * m_dim + c;
                    const double* Kcol = K + size_t(a * m_dim + c) * size_t(m);
                    for (int b = 0; b < nk; ++b) {
                        const Index w = verts[b];
                        if (w < v)
                            continue;
                        const int r0 = w == v ? c : 0;
                        const int* slot = std::lower_bound(ip + op[col], ip + op[col + 1], int(w * m_dim + r0));
                        double* target = cv + (slot - ip);
                        for (int rr = r0; rr < m_dim; ++rr)
                            target[rr - r0] += Kcol[b * m_dim + rr];
                    }
                }
            }
        }
    });
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

void SparseAssembler::add_matrix(const SparseMatrixd& lower)
{
    if (lower.rows() != m_matrix.rows() || lower.cols() != m_matrix.cols())
        throw std::logic_error("SparseAssembler::add_matrix: a " + std::to_string(lower.rows()) + " by "
            + std::to_string(lower.cols()) + " matrix into a pattern of size " + std::to_string(m_matrix.rows()));
    // Off-pattern entries, gathered per (column vertex, row vertex): a 2 dim square local each.
    std::map<uint64_t, Eigen::MatrixXd> extra;
    const int d = m_dim;
    for (Index col = 0; col < lower.outerSize(); ++col) {
        SparseMatrixd::InnerIterator target(m_matrix, col);
        for (SparseMatrixd::InnerIterator it(lower, col); it; ++it) {
            if (it.row() < col)
                continue;
            while (target && target.row() < it.row())
                ++target;
            if (target && target.row() == it.row()) {
                target.valueRef() += it.value();
                continue;
            }
            // A vertex's own block is always in the pattern: the rows lie in another vertex.
            Eigen::MatrixXd& K = extra[(uint64_t(col / d) << 32) | uint64_t(it.row() / d)];
            if (K.size() == 0)
                K.setZero(2 * d, 2 * d);
            const Index c = col % d, r = d + it.row() % d;
            K(r, c) += it.value();
            K(c, r) += it.value();
        }
    }
    for (const auto& [key, K] : extra) {
        const Index pair[2] = { Index(key >> 32), Index(key & 0xffffffffu) };
        add_local(pair, 2, K.data());
    }
}

void SparseAssembler::apply_constraints(const std::vector<char>& constrained)
{
    SparseMatrixd& A = matrix();
    double* values = A.valuePtr();
    const int* ip = A.innerIndexPtr();
    const int* op = A.outerIndexPtr();
    tbb::parallel_for(tbb::blocked_range<Index>(0, A.cols(), 1024), [&](const tbb::blocked_range<Index>& r) {
        for (Index col = r.begin(); col < r.end(); ++col)
            for (int k = op[col]; k < op[col + 1]; ++k) {
                const Index row = ip[k];
                if (constrained[size_t(row)] || constrained[size_t(col)])
                    values[k] = row == col ? 1.0 : 0.0;
            }
    });
}

} // namespace diffipc
