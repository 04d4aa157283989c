#pragma once
/// @file parallel.hpp
/// Parallel loops whose results do not depend on the number of threads.
///
/// - parallel_sum: a reduction over a fixed, thread-independent tree (fixed grain,
///   tbb::parallel_deterministic_reduce), so the rounding is the same for 1 or 16 threads.
/// - parallel_collect: an ordered filter/map, per fixed block, concatenated in block order.
/// - VertexScatter: adds per-item local vectors (an element's or a contact's gradient)
///   into a global vector by gathering per vertex: each vertex sums its items in
///   increasing item order, which is also the order of a serial scatter, so the result is
///   bitwise the serial one whatever the thread count.

#include "forward/common/types.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <cstdint>
#include <functional>
#include <vector>

namespace diffipc {

/// @brief sum_{k < n} term(k), deterministic for any thread count.
/// @param grain items per leaf of the fixed reduction tree
template <typename Term> double parallel_sum(size_t n, size_t grain, Term term)
{
    return tbb::parallel_deterministic_reduce(
        tbb::blocked_range<size_t>(0, n, grain), 0.0,
        [&](const tbb::blocked_range<size_t>& r, double sum) {
            for (size_t k = r.begin(); k < r.end(); ++k)
                sum += term(k);
            return sum;
        },
        std::plus<double>());
}

/// @brief Calls produce(k, out) for every k < n, in parallel over blocks of `block`
/// items; each call may push_back any number of T into `out`. Returns everything
/// produced, in the order of a serial loop over k.
template <typename T, typename Produce> std::vector<T> parallel_collect(size_t n, size_t block, Produce produce)
{
    const size_t num_blocks = (n + block - 1) / block;
    std::vector<std::vector<T>> parts(num_blocks);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, num_blocks), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t b = r.begin(); b < r.end(); ++b) {
            const size_t end = std::min(n, (b + 1) * block);
            for (size_t k = b * block; k < end; ++k)
                produce(k, parts[b]);
        }
    });
    std::vector<size_t> offset(num_blocks + 1, 0);
    for (size_t b = 0; b < num_blocks; ++b)
        offset[b + 1] = offset[b] + parts[b].size();
    std::vector<T> out(offset[num_blocks]);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, num_blocks), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t b = r.begin(); b < r.end(); ++b)
            std::move(parts[b].begin(), parts[b].end(), out.begin() + std::ptrdiff_t(offset[b]));
    });
    return out;
}

/// Vertex -> (item, local vertex) incidence, for deterministic parallel scatters.
class VertexScatter {
public:
    /// @brief Builds the incidence of `num_items` items with up to `slots` vertices each.
    /// @param num_vertices #V
    /// @param vertex_of    vertex_of(k, a): vertex a of item k, or a negative index for none
    template <typename VertexOf> void build(Index num_vertices, size_t num_items, int slots, VertexOf vertex_of)
    {
        m_slots = slots;
        m_offsets.assign(size_t(num_vertices) + 1, 0);
        for (size_t k = 0; k < num_items; ++k)
            for (int a = 0; a < slots; ++a) {
                const Index v = vertex_of(k, a);
                if (v >= 0)
                    ++m_offsets[size_t(v) + 1];
            }
        m_touched.clear();
        for (size_t v = 0; v < size_t(num_vertices); ++v) {
            if (m_offsets[v + 1] > 0)
                m_touched.push_back(Index(v));
            m_offsets[v + 1] += m_offsets[v];
        }
        m_codes.resize(size_t(m_offsets.back()));
        std::vector<int64_t> fill(m_offsets.begin(), m_offsets.end() - 1);
        for (size_t k = 0; k < num_items; ++k)
            for (int a = 0; a < slots; ++a) {
                const Index v = vertex_of(k, a);
                if (v >= 0)
                    m_codes[size_t(fill[size_t(v)]++)] = int64_t(k) * slots + a;
            }
    }

    /// @brief out[v dim + i] += scale * local[(k slots + a) dim + i] for every incidence
    /// (v = vertex a of item k), each vertex's items in increasing k.
    /// @param local #items * slots * dim values, item-major (an item's vertex a at offset (k slots + a) dim)
    void add(const double* local, int dim, double scale, VectorXd& out) const
    {
        tbb::parallel_for(
            tbb::blocked_range<size_t>(0, m_touched.size(), 256), [&](const tbb::blocked_range<size_t>& r) {
                for (size_t t = r.begin(); t < r.end(); ++t) {
                    const Index v = m_touched[t];
                    for (int i = 0; i < dim; ++i) {
                        double acc = out[v * dim + i];
                        for (int64_t c = m_offsets[size_t(v)]; c < m_offsets[size_t(v) + 1]; ++c)
                            acc += scale * local[size_t(m_codes[size_t(c)]) * size_t(dim) + size_t(i)];
                        out[v * dim + i] = acc;
                    }
                }
            });
    }

    /// Vertices with at least one item, increasing.
    const std::vector<Index>& touched() const { return m_touched; }
    /// Codes k * slots + a of vertex v's incidences, increasing.
    const int64_t* begin(Index v) const { return m_codes.data() + m_offsets[size_t(v)]; }
    const int64_t* end(Index v) const { return m_codes.data() + m_offsets[size_t(v) + 1]; }
    int slots() const { return m_slots; }

private:
    int m_slots = 0;
    std::vector<int64_t> m_offsets; // #V + 1
    std::vector<int64_t> m_codes;
    std::vector<Index> m_touched;
};

} // namespace diffipc
