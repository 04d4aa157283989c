#include "forward/contact/broad_phase/bvh.hpp"

#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace diffipc {

namespace {

    /// Below this many primitives a subtree is built serially.
    constexpr size_t PARALLEL_CUTOFF = 4096;

    /// A primitive's box centre, stored by value so that the partitioning below touches contiguous memory.
    struct Item {
        double centre[3];
        uint32_t id;
    };

    /// Orders items[begin, end) for a subtree of `capacity` primitive slots (a power of two): split at
    /// begin + min(m, capacity / 2) along the longest axis of the centres (a median split whenever the range fills
    /// more than half the capacity), so that the leaves of the complete tree hold the primitives left to right and
    /// the free slots end up on the right. Ranges no larger than a leaf are left as they are.
    void order_subtree(std::vector<Item>& items, size_t begin, size_t end, size_t capacity)
    {
        const size_t m = end - begin;
        if (m <= 1 || capacity <= BVH::LEAF_SIZE)
            return;
        const size_t mid = begin + std::min(m, capacity / 2);
        if (mid < end) {
            double lo[3], hi[3];
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::numeric_limits<double>::infinity();
                hi[k] = -lo[k];
            }
            for (size_t i = begin; i < end; ++i)
                for (int k = 0; k < 3; ++k) {
                    lo[k] = std::min(lo[k], items[i].centre[k]);
                    hi[k] = std::max(hi[k], items[i].centre[k]);
                }
            int axis = 0;
            for (int k = 1; k < 3; ++k)
                if (hi[k] - lo[k] > hi[axis] - lo[axis])
                    axis = k;
            // A strict total order (ties broken by id) makes the split independent of the nth_element implementation.
            std::nth_element(items.begin() + std::ptrdiff_t(begin), items.begin() + std::ptrdiff_t(mid),
                items.begin() + std::ptrdiff_t(end), [axis](const Item& a, const Item& b) {
                    return a.centre[axis] < b.centre[axis] || (a.centre[axis] == b.centre[axis] && a.id < b.id);
                });
        }
        const auto left = [&] { order_subtree(items, begin, mid, capacity / 2); };
        const auto right = [&] { order_subtree(items, mid, end, capacity / 2); };
        if (m > PARALLEL_CUTOFF) {
            tbb::parallel_invoke(left, right);
        } else {
            left();
            right();
        }
    }

} // namespace

void BVH::build(const std::vector<AABB>& boxes)
{
    const size_t n = boxes.size();
    if (n > (size_t(1) << 30))
        throw std::length_error("BVH::build: more than 2^30 primitives");
    m_num_primitives = n;
    m_nodes.clear();
    m_sorted_primitives.clear();
    m_sorted_boxes.clear();
    m_num_leaves = 0;
    if (n == 0)
        return;

    // Box centres; non-finite ones (empty boxes) are sent to the end.
    std::vector<Item> items(n);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i < r.end(); ++i) {
            const Eigen::Array3d c = 0.5 * (boxes[i].min + boxes[i].max);
            for (int k = 0; k < 3; ++k)
                items[i].centre[k] = c.allFinite() ? c[k] : std::numeric_limits<double>::max();
            items[i].id = uint32_t(i);
        }
    });

    m_num_leaves = 1;
    while (size_t(m_num_leaves) * LEAF_SIZE < n)
        m_num_leaves *= 2;
    order_subtree(items, 0, n, size_t(m_num_leaves) * LEAF_SIZE);
    m_sorted_primitives.resize(n);
    for (size_t k = 0; k < n; ++k)
        m_sorted_primitives[k] = items[k].id;

    m_sorted_boxes.resize(n);
    m_nodes.assign(2 * size_t(m_num_leaves), AABB::empty());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, m_num_leaves, 1024), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t leaf = r.begin(); leaf < r.end(); ++leaf) {
            AABB& node = m_nodes[m_num_leaves + leaf];
            for (size_t k = leaf * LEAF_SIZE; k < std::min((leaf + 1) * LEAF_SIZE, n); ++k) {
                m_sorted_boxes[k] = boxes[m_sorted_primitives[k]];
                node.extend(m_sorted_boxes[k]);
            }
        }
    });

    // Internal nodes level by level, from the level above the leaves up to the root.
    for (size_t level_begin = m_num_leaves / 2; level_begin >= 1; level_begin /= 2) {
        tbb::parallel_for(
            tbb::blocked_range<size_t>(level_begin, 2 * level_begin, 2048), [&](const tbb::blocked_range<size_t>& r) {
                for (size_t i = r.begin(); i < r.end(); ++i) {
                    AABB box = m_nodes[2 * i];
                    box.extend(m_nodes[2 * i + 1]);
                    m_nodes[i] = box;
                }
            });
    }
}

} // namespace diffipc
