#pragma once
/// @file bvh.hpp
/// Static bounding volume hierarchy over a list of boxes: a complete binary
/// tree in implicit (heap) layout, built top-down by splitting the primitives
/// at the median of their box centres along the longest axis of the centres'
/// bounds (subtrees in parallel), with a few primitives per leaf, then
/// fitting the node boxes bottom-up.
/// Building is O(n log n); a query visits O(log n + k) nodes for k hits on
/// well-distributed boxes, and long boxes (large sweeps) cost no more than
/// their overlaps.

#include "forward/contact/broad_phase/aabb.hpp"

#include <algorithm>
#include <cstdint>
#include <vector>

namespace diffipc {

class BVH {
public:
    /// @brief Builds the tree over `boxes` (index i of the list is primitive i). Replaces any previous tree.
    /// @param boxes  #B boxes (empty boxes are allowed and never reported)
    void build(const std::vector<AABB>& boxes);

    /// @brief Calls f(i) once for every primitive i whose box intersects `box`, in tree order.
    /// Thread-safe for concurrent queries.
    template <typename F> void query(const AABB& box, F&& f) const
    {
        if (m_num_primitives == 0)
            return;
        // The depth is log2(#leaves) <= 30 and the stack holds at most one pending sibling per level.
        uint32_t stack[64];
        int top = 0;
        stack[top++] = 1;
        while (top > 0) {
            const uint32_t node = stack[--top];
            if (!m_nodes[node].intersects(box))
                continue;
            if (node >= m_num_leaves) {
                const size_t begin = size_t(node - m_num_leaves) * LEAF_SIZE;
                const size_t end = std::min(begin + LEAF_SIZE, m_num_primitives);
                for (size_t k = begin; k < end; ++k)
                    if (m_sorted_boxes[k].intersects(box))
                        f(Index(m_sorted_primitives[k]));
            } else {
                stack[top++] = 2 * node + 1;
                stack[top++] = 2 * node;
            }
        }
    }

    size_t num_primitives() const { return m_num_primitives; }

    /// Primitives per leaf.
    static constexpr size_t LEAF_SIZE = 4;

private:
    /// Heap layout, 1-based: node i has children 2i and 2i+1; leaves are m_num_leaves .. 2 m_num_leaves - 1, leaf
    /// l holding the sorted primitives l * LEAF_SIZE .. (l + 1) * LEAF_SIZE - 1 (padding leaves, at the end, hold
    /// none and have empty boxes).
    std::vector<AABB> m_nodes;
    /// Primitive ids in leaf order, and their boxes in the same order (contiguous for the leaf scans).
    std::vector<uint32_t> m_sorted_primitives;
    std::vector<AABB> m_sorted_boxes;
    /// Number of leaves, a power of two.
    uint32_t m_num_leaves = 0;
    size_t m_num_primitives = 0;
};

} // namespace diffipc
