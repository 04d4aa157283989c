#pragma once
/// @file hash_grid.hpp
/// Uniform grid over a list of boxes (a "spatial hash" whose key is the exact
/// linear cell index, so keys never collide; only non-empty cells are stored):
/// every box is listed in each cell it overlaps, and the (cell, box) list is
/// radix-sorted by cell. A query visits the cells of its box; a box that shares
/// several cells with the query is reported only from the cell holding the
/// minimum corner of the two boxes' intersection, so each hit is reported once
/// without deduplication.
///
/// Cell size: the median box extent (longest side), robust to a few very large
/// boxes. Boxes longer than LARGE_CELLS cells (a ground plane made of two
/// triangles, a long sweep) are kept out of the grid in a short list that every
/// query scans; at most max(32, #B / 256) boxes go there, the cell size growing
/// if more would. The cell size then doubles while the gridded boxes would
/// occupy more than 27 (3D) or 9 (2D) cells each on average. A query costs
/// O(cells visited + boxes in them + large boxes), where the cells visited
/// are at most the non-empty ones. Best when most boxes have similar sizes;
/// with a continuum of sizes (large, uneven sweeps) the BVH does better.

#include "forward/contact/broad_phase/aabb.hpp"

#include <algorithm>
#include <cstdint>
#include <vector>

namespace diffipc {

class HashGrid {
public:
    /// @brief Builds the grid over `boxes` (index i of the list is primitive i). Replaces any previous grid.
    /// @param boxes  #B boxes, all finite (2D boxes have z = 0)
    /// @param dim    2 or 3
    void build(const std::vector<AABB>& boxes, int dim);

    /// @brief Calls f(i) once for every primitive i whose box intersects `box`. Thread-safe for concurrent queries.
    template <typename F> void query(const AABB& box, F&& f) const
    {
        if (!(box.min <= box.max).all())
            return;
        for (uint32_t j : m_large)
            if (box.intersects(m_boxes[j]))
                f(Index(j));
        if (m_cell_keys.empty())
            return;
        uint64_t lo[3], hi[3];
        double range_cells = 1;
        for (int k = 0; k < 3; ++k) {
            lo[k] = cell_coordinate(box.min[k], k);
            hi[k] = cell_coordinate(box.max[k], k);
            range_cells *= double(hi[k] - lo[k] + 1);
        }
        const auto visit_cell = [&](size_t c) {
            for (size_t e = m_cell_start[c]; e < m_cell_start[c + 1]; ++e) {
                const uint32_t j = m_box_ids[e];
                const AABB& other = m_boxes[j];
                if (box.intersects(other) && key_of(box.min.max(other.min)) == m_cell_keys[c])
                    f(Index(j));
            }
        };
        if (range_cells > double(m_cell_keys.size())) {
            // A query larger than the occupied part of the grid: scan the non-empty cells instead.
            for (size_t c = 0; c < m_cell_keys.size(); ++c) {
                const uint64_t key = m_cell_keys[c];
                const uint64_t z = key % uint64_t(m_dims[2]), xy = key / uint64_t(m_dims[2]);
                const uint64_t y = xy % uint64_t(m_dims[1]), x = xy / uint64_t(m_dims[1]);
                if (lo[0] <= x && x <= hi[0] && lo[1] <= y && y <= hi[1] && lo[2] <= z && z <= hi[2])
                    visit_cell(c);
            }
            return;
        }
        for (uint64_t x = lo[0]; x <= hi[0]; ++x)
            for (uint64_t y = lo[1]; y <= hi[1]; ++y) {
                // Cells (x, y, lo[2]..hi[2]) have consecutive keys: one search per column.
                const uint64_t first = cell_key(x, y, lo[2]), last = cell_key(x, y, hi[2]);
                auto it = std::lower_bound(m_cell_keys.begin(), m_cell_keys.end(), first);
                for (; it != m_cell_keys.end() && *it <= last; ++it)
                    visit_cell(size_t(it - m_cell_keys.begin()));
            }
    }

    /// Edge length of the cubic cells (m).
    double cell_size() const { return m_cell_size; }
    /// Number of (cell, box) incidences.
    size_t num_entries() const { return m_box_ids.size(); }
    /// Number of boxes kept out of the grid.
    size_t num_large() const { return m_large.size(); }

    /// A box longer than this many cells along an axis is not gridded.
    static constexpr double LARGE_CELLS = 8;

private:
    /// At most 2^21 cells per axis, so that linear cell indices fit in 63 bits.
    static constexpr int KEY_BITS = 21;

    /// Cell coordinate of x along axis k, clamped to the grid; monotone in x.
    uint64_t cell_coordinate(double x, int k) const
    {
        const double s = (x - m_origin[k]) * m_inv_cell_size;
        if (!(s > 0))
            return 0;
        if (s >= double(m_dims[k] - 1))
            return uint64_t(m_dims[k] - 1);
        return uint64_t(s);
    }

    /// Linear index of cell (x, y, z); z varies fastest.
    uint64_t cell_key(uint64_t x, uint64_t y, uint64_t z) const
    {
        return (x * uint64_t(m_dims[1]) + y) * uint64_t(m_dims[2]) + z;
    }

    uint64_t key_of(const Eigen::Array3d& p) const
    {
        return cell_key(cell_coordinate(p[0], 0), cell_coordinate(p[1], 1), cell_coordinate(p[2], 2));
    }

    /// Copy of the boxes the grid was built over.
    std::vector<AABB> m_boxes;
    Eigen::Array3d m_origin = Eigen::Array3d::Zero();
    double m_cell_size = 1;
    double m_inv_cell_size = 1;
    int64_t m_dims[3] = { 1, 1, 1 };
    /// Sorted keys of the non-empty cells.
    std::vector<uint64_t> m_cell_keys;
    /// Boxes of cell c are m_box_ids[m_cell_start[c] .. m_cell_start[c + 1]).
    std::vector<size_t> m_cell_start;
    std::vector<uint32_t> m_box_ids;
    /// Boxes kept out of the grid, increasing.
    std::vector<uint32_t> m_large;
};

} // namespace diffipc
