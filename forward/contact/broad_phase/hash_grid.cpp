#include "forward/contact/broad_phase/hash_grid.hpp"

#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <utility>

namespace diffipc {

void HashGrid::build(const std::vector<AABB>& boxes, int dim)
{
    const size_t n = boxes.size();
    if (n >= (size_t(1) << 32))
        throw std::length_error("HashGrid::build: more than 2^32 boxes");
    m_boxes = boxes;
    m_cell_keys.clear();
    m_cell_start.clear();
    m_box_ids.clear();
    m_large.clear();
    m_dims[0] = m_dims[1] = m_dims[2] = 1;
    if (n == 0)
        return;

    // Extent (longest side) of each box, -1 for empty boxes, and the domain.
    std::vector<double> extent(n);
    const AABB domain = tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, n, 4096), AABB::empty(),
        [&](const tbb::blocked_range<size_t>& r, AABB acc) {
            for (size_t i = r.begin(); i < r.end(); ++i) {
                const AABB& b = boxes[i];
                if (!(b.min <= b.max).all()) {
                    extent[i] = -1;
                    continue;
                }
                acc.extend(b);
                extent[i] = (b.max - b.min).head(dim).maxCoeff();
            }
            return acc;
        },
        [](AABB x, const AABB& y) {
            x.extend(y);
            return x;
        });
    std::vector<double> sorted_extent;
    sorted_extent.reserve(n);
    for (double e : extent)
        if (e >= 0)
            sorted_extent.push_back(e);
    if (sorted_extent.empty())
        return;
    const Eigen::Array3d domain_extent = domain.max - domain.min;
    m_origin = domain.min;

    // Median extent, raised so that at most max_large boxes are longer than LARGE_CELLS cells.
    const size_t count = sorted_extent.size();
    std::nth_element(sorted_extent.begin(), sorted_extent.begin() + std::ptrdiff_t(count / 2), sorted_extent.end());
    double h = sorted_extent[count / 2];
    const size_t max_large = std::max<size_t>(32, count / 256);
    if (max_large < count) {
        std::nth_element(sorted_extent.begin(), sorted_extent.begin() + std::ptrdiff_t(max_large), sorted_extent.end(),
            std::greater<double>());
        h = std::max(h, sorted_extent[max_large] / LARGE_CELLS);
    }
    // Point-like boxes (zero inflation, static vertices) can make the extent 0 or denormal.
    const auto usable = [](double s) { return s > 0 && std::isfinite(s) && std::isfinite(1.0 / s); };
    if (!usable(h))
        h = domain_extent.head(dim).maxCoeff();
    if (!usable(h))
        h = 1;

    const auto is_large = [&](size_t i) { return extent[i] > LARGE_CELLS * m_cell_size; };
    const auto count_cells = [&](size_t i) -> uint64_t {
        if (extent[i] < 0 || is_large(i))
            return 0;
        const AABB& b = boxes[i];
        uint64_t c = 1;
        for (int k = 0; k < dim; ++k)
            c *= cell_coordinate(b.max[k], k) - cell_coordinate(b.min[k], k) + 1;
        return c;
    };
    const uint64_t max_entries = uint64_t(n) * (dim == 3 ? 27 : 9);
    const int64_t max_dims = int64_t(1) << KEY_BITS;
    for (int rounds = 0;; ++rounds) {
        // Doubling from a finite h reaches any finite extent in under 2100 rounds; boxes
        // with infinite or overflowing coordinates would make this loop endless.
        if (!std::isfinite(h) || rounds > 2100)
            throw std::runtime_error("broad phase: coordinates beyond the range a grid can cover (not finite or "
                                     "near the largest double); the scene places or moves something out of range");
        m_cell_size = h;
        m_inv_cell_size = 1.0 / h;
        bool fits = true;
        for (int k = 0; k < 3; ++k) {
            const double cells = k < dim ? std::floor(domain_extent[k] * m_inv_cell_size) + 1 : 1;
            fits = fits && cells <= double(max_dims);
            m_dims[k] = fits ? int64_t(cells) : max_dims;
        }
        if (fits) {
            const uint64_t total = tbb::parallel_reduce(
                tbb::blocked_range<size_t>(0, n, 4096), uint64_t(0),
                [&](const tbb::blocked_range<size_t>& r, uint64_t acc) {
                    for (size_t i = r.begin(); i < r.end(); ++i)
                        acc += count_cells(i);
                    return acc;
                },
                [](uint64_t x, uint64_t y) { return x + y; });
            if (total <= max_entries)
                break;
        }
        h *= 2;
    }
    for (size_t i = 0; i < n; ++i)
        if (extent[i] >= 0 && is_large(i))
            m_large.push_back(uint32_t(i));

    // List every box in every cell it overlaps, in box order, then sort the (cell, box) entries by cell with a
    // stable LSD radix sort on the linear cell index (O(entries) for the few digits the grid needs); stability keeps
    // the boxes of a cell in increasing order.
    std::vector<uint64_t> offset(n + 1, 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i < r.end(); ++i)
            offset[i + 1] = count_cells(i);
    });
    for (size_t i = 0; i < n; ++i)
        offset[i + 1] += offset[i];
    const size_t num_entries = offset[n];
    std::vector<uint64_t> keys(num_entries);
    std::vector<uint32_t> ids(num_entries);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1024), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i < r.end(); ++i) {
            if (offset[i + 1] == offset[i])
                continue;
            const AABB& b = boxes[i];
            uint64_t lo[3] = { 0, 0, 0 }, hi[3] = { 0, 0, 0 };
            for (int k = 0; k < dim; ++k) {
                lo[k] = cell_coordinate(b.min[k], k);
                hi[k] = cell_coordinate(b.max[k], k);
            }
            size_t e = offset[i];
            for (uint64_t x = lo[0]; x <= hi[0]; ++x)
                for (uint64_t y = lo[1]; y <= hi[1]; ++y)
                    for (uint64_t z = lo[2]; z <= hi[2]; ++z) {
                        keys[e] = cell_key(x, y, z);
                        ids[e++] = uint32_t(i);
                    }
        }
    });

    const uint64_t max_key = uint64_t(m_dims[0]) * uint64_t(m_dims[1]) * uint64_t(m_dims[2]) - 1;
    constexpr int DIGIT_BITS = 11;
    constexpr size_t BUCKETS = size_t(1) << DIGIT_BITS;
    std::vector<uint64_t> keys_tmp(num_entries);
    std::vector<uint32_t> ids_tmp(num_entries);
    std::vector<size_t> bucket(BUCKETS + 1);
    for (int shift = 0; shift < 64 && (max_key >> shift) != 0; shift += DIGIT_BITS) {
        std::fill(bucket.begin(), bucket.end(), 0);
        for (size_t e = 0; e < num_entries; ++e)
            ++bucket[((keys[e] >> shift) & (BUCKETS - 1)) + 1];
        for (size_t d = 0; d < BUCKETS; ++d)
            bucket[d + 1] += bucket[d];
        for (size_t e = 0; e < num_entries; ++e) {
            const size_t to = bucket[(keys[e] >> shift) & (BUCKETS - 1)]++;
            keys_tmp[to] = keys[e];
            ids_tmp[to] = ids[e];
        }
        keys.swap(keys_tmp);
        ids.swap(ids_tmp);
    }

    m_box_ids = std::move(ids);
    for (size_t e = 0; e < num_entries; ++e) {
        if (e == 0 || keys[e] != keys[e - 1]) {
            m_cell_keys.push_back(keys[e]);
            m_cell_start.push_back(e);
        }
    }
    m_cell_start.push_back(num_entries);
}

} // namespace diffipc
